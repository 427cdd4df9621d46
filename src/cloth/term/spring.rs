//! Springs as terms: between two free particles ([`Springs`]) and from a free particle to a
//! pinned point ([`Anchors`]), each with the fabric's law of [`crate::cloth::law`] (the
//! gradient and projected block of [`spring_terms`], the energy of [`spring_energy`], the sweeps'
//! local step of [`spring_local`]).

use glam::{DMat3, DVec3};

use super::{Local, Term};
use crate::cloth::law::{spring_energy, spring_local, spring_terms};
use crate::cloth::system::{self, FreeSprings};

/// The springs between free particles, at a jamming strain.
#[derive(Debug, Clone, Copy)]
pub struct Springs<'a> {
    /// The springs.
    pub set: &'a FreeSprings,
    /// Compression strain past which a spring softer in compression jams.
    pub jam: f64,
}

impl Term<2> for Springs<'_> {
    fn len(&self) -> usize {
        self.set.a.len()
    }

    #[inline]
    fn vertices(&self, e: usize) -> [u32; 2] {
        [self.set.a[e], self.set.b[e]]
    }

    #[inline]
    fn energy(&self, e: usize, x: &[DVec3]) -> f64 {
        let s = self.set;
        let len = x[s.a[e] as usize].distance(x[s.b[e] as usize]);
        spring_energy(len, s.rest[e], s.k[e], s.kc[e], self.jam)
    }

    #[inline]
    fn derivatives(&self, e: usize, x: &[DVec3], local: &mut Local<2>) {
        let s = self.set;
        let r = x[s.a[e] as usize] - x[s.b[e] as usize];
        let (f, he) = spring_terms(r, s.rest[e], s.k[e], s.kc[e], self.jam);
        local.gradient = [f, -f];
        let minus = he.map(|row| row.map(|h| -h));
        local.hessian = [[he, minus], [minus, he]];
    }

    #[inline(always)]
    fn add_local(&self, e: usize, a: usize, x: &[DVec3], g: &mut DVec3, h: &mut DMat3) {
        let s = self.set;
        let (me, other) = if a == 0 {
            (s.a[e], s.b[e])
        } else {
            (s.b[e], s.a[e])
        };
        let r = x[me as usize] - x[other as usize];
        add_spring(r, s.rest[e], s.k[e], s.kc[e], self.jam, g, h);
    }
}

/// One spring's local step at the end `r` points from ([`spring_local`]).
#[inline(always)]
fn add_spring(r: DVec3, rest: f64, k: f64, kc: f64, jam: f64, g: &mut DVec3, h: &mut DMat3) {
    if let Some((f, t, across)) = spring_local(r, rest, k, kc, jam) {
        *g += f;
        *h += across + DMat3::from_diagonal(DVec3::splat(t));
    }
}

/// The springs from free particles to pinned points, at a jamming strain.
#[derive(Debug, Clone, Copy)]
pub struct Anchors<'a> {
    /// The anchors.
    pub set: &'a system::Anchors,
    /// Compression strain past which a spring softer in compression jams.
    pub jam: f64,
}

impl Term<1> for Anchors<'_> {
    fn len(&self) -> usize {
        self.set.a.len()
    }

    #[inline]
    fn vertices(&self, e: usize) -> [u32; 1] {
        [self.set.a[e]]
    }

    #[inline]
    fn energy(&self, e: usize, x: &[DVec3]) -> f64 {
        let an = self.set;
        let len = x[an.a[e] as usize].distance(an.at[e]);
        spring_energy(len, an.rest[e], an.k[e], an.kc[e], self.jam)
    }

    #[inline]
    fn derivatives(&self, e: usize, x: &[DVec3], local: &mut Local<1>) {
        let an = self.set;
        let r = x[an.a[e] as usize] - an.at[e];
        let (f, he) = spring_terms(r, an.rest[e], an.k[e], an.kc[e], self.jam);
        local.gradient[0] = f;
        local.hessian[0][0] = he;
    }

    #[inline(always)]
    fn add_local(&self, e: usize, _a: usize, x: &[DVec3], g: &mut DVec3, h: &mut DMat3) {
        let an = self.set;
        let r = x[an.a[e] as usize] - an.at[e];
        add_spring(r, an.rest[e], an.k[e], an.kc[e], self.jam, g, h);
    }
}
