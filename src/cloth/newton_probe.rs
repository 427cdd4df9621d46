//! Diagnostics for Newton on real garments (ignored test, run by hand):
//!
//! ```text
//! PROBE_MESH=dress_draped.obj PROBE_COLLIDER=mannequin.obj PROBE_STEPS=3 \
//!     cargo test --release --lib newton::probe -- --ignored --nocapture
//! ```
//!
//! Other knobs: `PROBE_PIN` (a `--pin` spec), `PROBE_SHAPE` (a `--collider` spec instead of a
//! mesh), `PROBE_JAM`, `PROBE_BEND_REST` (`flat` or `mesh`), `PROBE_SUBSTEPS`, `PROBE_BEND`,
//! `PROBE_THICKNESS`, `PROBE_FRICTION`, `PROBE_CAP`, `PROBE_TRANSLATE` (x,y,z in metres, as
//! the garments bench raises circle_skirt above the table), `PROBE_CONTACT` (`constraint` or
//! `barrier`), `PROBE_DOUBLE` (set: double-precision factors only); every step also prints the
//! line search's step lengths α.
//!
//! Prints the mesh's flaws, the springs' and bending stencils' stiffness spread, how many
//! particles start within the collision thickness, and per step the residual at every Newton
//! iterate and the largest stretch and compression.

// A diagnostic run by hand: printing is its output.
#![allow(clippy::print_stdout)]

use std::collections::BTreeMap;
use std::path::PathBuf;

use glam::DVec3;

use super::*;
use crate::bake::cloth::{prepare_cloth, ClothJob, ClothSource};
use crate::cloth::collide::ColliderSpec;

fn env<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

struct Flags {
    non_manifold: Vec<bool>,
    sliver: Vec<bool>,
    boundary: Vec<bool>,
}

fn flags(mesh: &crate::mesh::Mesh) -> Flags {
    let n = mesh.positions.len();
    let mut edges: BTreeMap<(u32, u32), usize> = BTreeMap::new();
    for t in &mesh.triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut f = Flags {
        non_manifold: vec![false; n],
        sliver: vec![false; n],
        boundary: vec![false; n],
    };
    for (&(a, b), &c) in &edges {
        let (a, b) = (a as usize, b as usize);
        if c > 2 {
            f.non_manifold[a] = true;
            f.non_manifold[b] = true;
        }
        if c == 1 {
            f.boundary[a] = true;
            f.boundary[b] = true;
        }
        if mesh.positions[a].distance(mesh.positions[b]) < 0.002 {
            f.sliver[a] = true;
            f.sliver[b] = true;
        }
    }
    f
}

#[test]
#[ignore]
fn probe() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("meshes/garments");
    let mesh: String = env("PROBE_MESH", "dress_draped.obj".to_string());
    let collider: String = env("PROBE_COLLIDER", "mannequin.obj".to_string());
    let steps: usize = env("PROBE_STEPS", 3);
    let cap: usize = env("PROBE_CAP", 50);
    let mut job = ClothJob::new(ClothSource::File(root.join(&mesh)), "unused.glb".into());
    if let Ok(shape) = std::env::var("PROBE_SHAPE") {
        job.collider = vec![shape.parse().unwrap()];
    } else if collider != "none" {
        job.collider = vec![ColliderSpec::mesh(root.join(&collider))];
    }
    if let Ok(b) = std::env::var("PROBE_BEND") {
        job.bend = Some(b.parse().unwrap());
    }
    if let Ok(t) = std::env::var("PROBE_THICKNESS") {
        job.thickness = Some(t.parse().unwrap());
    }
    if let Ok(p) = std::env::var("PROBE_PIN") {
        job.pin = vec![p.parse().unwrap()];
    }
    if let Ok(t) = std::env::var("PROBE_TRANSLATE") {
        job.translate = Some(crate::spec::vec3_value(&t).unwrap());
    }
    if let Ok(n) = std::env::var("PROBE_SUBSTEPS") {
        job.substeps = n.parse().unwrap();
    }
    if let Ok(r) = std::env::var("PROBE_BEND_REST") {
        use crate::cloth::material::BendRest;
        job.bend_rest = Some(match r.as_str() {
            "flat" => BendRest::Flat,
            "mesh" => BendRest::Mesh,
            _ => panic!("PROBE_BEND_REST is `flat` or `mesh`, not {r:?}"),
        });
    }
    if let Ok(c) = std::env::var("PROBE_CONTACT") {
        use crate::cloth::collide::ContactModel;
        job.contact = Some(match c.as_str() {
            "constraint" => ContactModel::Constraint,
            "barrier" => ContactModel::Barrier,
            _ => panic!("PROBE_CONTACT is `constraint` or `barrier`, not {c:?}"),
        });
    }
    if let Ok(j) = std::env::var("PROBE_JAM") {
        job.jam_strain = Some(j.parse().unwrap());
    }
    job.frames = Some(steps);
    job.friction = env("PROBE_FRICTION", job.friction);
    let prepared = prepare_cloth(&job).unwrap();
    let model = &prepared.model;
    let params = &prepared.params;
    let fl = flags(&model.mesh);
    let count = |f: &[bool]| f.iter().filter(|&&b| b).count();
    println!(
        "particles on non-manifold edges {}, on edges < 2 mm {}, on the boundary {}",
        count(&fl.non_manifold),
        count(&fl.sliver),
        count(&fl.boundary)
    );
    let sys = ReducedSystem::with_coupling(
        model,
        params.step_params(),
        super::BendingFactor::default().coupling(),
    )
    .unwrap();
    let colliders = (!params.colliders.is_empty()).then(|| params.colliders.clone());
    println!(
        "{} particles, {} springs, {} bends, thickness {:?} m, h {} s, force scale {:.3e} N",
        sys.len(),
        sys.springs.a.len(),
        sys.bends.len(),
        colliders.as_ref().map(|c| c.thickness),
        sys.params.time_step,
        sys.force_scale()
    );
    {
        let k = &sys.springs.k;
        let mut ks = k.clone();
        ks.sort_by(f64::total_cmp);
        println!(
            "spring k: min {:.3e} median {:.3e} max {:.3e}",
            ks[0],
            ks[ks.len() / 2],
            ks[ks.len() - 1]
        );
        let mut bw: Vec<f64> = sys
            .bends
            .w
            .iter()
            .map(|w| w.iter().map(|x| x * x).sum::<f64>())
            .collect();
        bw.sort_by(f64::total_cmp);
        if !bw.is_empty() {
            println!(
                "bend Σw² (N/m): median {:.3e} p99 {:.3e} max {:.3e}",
                bw[bw.len() / 2],
                bw[bw.len() * 99 / 100],
                bw[bw.len() - 1]
            );
        }
    }
    let x_model = model.positions().to_vec();
    let mut x = sys.gather(&x_model);
    // Contact at rest.
    if let Some(c) = &colliders {
        let t = c.thickness;
        let (mut inside, mut within, mut near) = (0, 0, 0);
        let mut depths = Vec::new();
        for p in &x {
            for shape in &c.shapes {
                if let Some(s) = shape.contact(*p, *p, 3.0 * t) {
                    if s.distance < 0.0 {
                        inside += 1;
                    }
                    if s.distance < t {
                        within += 1;
                        depths.push(t - s.distance);
                    } else if s.distance < 3.0 * t {
                        near += 1;
                    }
                }
            }
        }
        depths.sort_by(f64::total_cmp);
        println!(
            "frame 0: {inside} particles behind the surface, {within} within the thickness \
             (depth t−φ median {:.2e} max {:.2e} m), {near} within 3 t",
            depths.get(depths.len() / 2).copied().unwrap_or(0.0),
            depths.last().copied().unwrap_or(0.0)
        );
    }
    let mut solver = NewtonSolver::new(sys, params.tolerance, cap)
        .unwrap()
        .single_precision(std::env::var("PROBE_DOUBLE").is_err())
        .with_sweeps(env("PROBE_SWEEPS", crate::cloth::newton::DEFAULT_SWEEPS))
        .with_colliders(colliders);
    solver.record_history(true);
    let mut v = vec![DVec3::ZERO; x.len()];
    for step in 1..=steps {
        let t0 = std::time::Instant::now();
        let stats = solver.step(&mut x, &mut v).unwrap();
        let joined = |v: Option<&[f64]>, f: fn(&f64) -> String| {
            v.unwrap().iter().map(f).collect::<Vec<_>>().join(" ")
        };
        println!(
            "step {step}: {stats:?} {:.2} s, directions (single, double) so far {:?}\n  ρ: {}\n  α: {}",
            t0.elapsed().as_secs_f64(),
            (solver.directions_by_precision(), solver.sweep_passes()),
            joined(solver.history(), |r| format!("{r:.2e}")),
            joined(solver.step_lengths(), |a| format!("{a:.3}"))
        );
        report_terms(&solver, &x, &fl);
        // Strain.
        let sp = &solver.sys.springs;
        let (mut hi, mut lo) = (0.0f64, 0.0f64);
        let (mut ihi, mut ilo) = (0, 0);
        let mut past = 0;
        for s in 0..sp.a.len() {
            let e = x[sp.a[s] as usize].distance(x[sp.b[s] as usize]) / sp.rest[s] - 1.0;
            if e.abs() > 0.1 {
                past += 1;
            }
            if e > hi {
                hi = e;
                ihi = s;
            }
            if e < lo {
                lo = e;
                ilo = s;
            }
        }
        let pof = |i: u32| solver.sys.particle_of[i as usize];
        println!(
            "step {step}: strain max {:+.1} % (spring {}-{}, rest {:.2} mm), min {:+.1} % (spring {}-{}, rest {:.2} mm), {past} edges past 10 %",
            100.0 * hi,
            pof(sp.a[ihi]),
            pof(sp.b[ihi]),
            1e3 * sp.rest[ihi],
            100.0 * lo,
            pof(sp.a[ilo]),
            pof(sp.b[ilo]),
            1e3 * sp.rest[ilo]
        );
    }
}

/// The gradient's terms at the end of a step: inertia, springs, bending, and what the colliders
/// hold (∇g less the free gradient), as RMS per particle relative to its weight, and the worst
/// particles with their flags (N non-manifold, S sliver, B boundary, H held).
fn report_terms(s: &NewtonSolver, x: &[DVec3], fl: &Flags) {
    let sys = &s.sys;
    let n = x.len();
    let h = sys.params.time_step;
    let w = sys.inertia_scale() / (h * h);
    let mut t = vec![[DVec3::ZERO; 4]; n];
    for i in 0..n {
        t[i][0] = (x[i] - s.y[i]) * (w * sys.mass[i]);
        t[i][3] = s.grad[i] - s.free_grad[i];
    }
    let sp = &sys.springs;
    for k in 0..sp.a.len() {
        let (a, b) = (sp.a[k] as usize, sp.b[k] as usize);
        let f = crate::cloth::system::spring_gradient(
            x[a] - x[b],
            sp.rest[k],
            sp.k[k],
            sp.kc[k],
            sys.jam_strain,
        );
        t[a][1] += f;
        t[b][1] -= f;
    }
    let mut bend = vec![DVec3::ZERO; n];
    sys.add_bending_gradient(x, &mut bend);
    for i in 0..n {
        t[i][2] = bend[i];
    }
    let scale = sys.force_scale();
    let norms: Vec<String> = (0..4)
        .map(|k| {
            format!(
                "{:.2e}",
                t.iter().map(|v| v[k].length_squared()).sum::<f64>().sqrt() / scale
            )
        })
        .collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| {
        s.free_grad[b]
            .length_squared()
            .total_cmp(&s.free_grad[a].length_squared())
    });
    let total: f64 = s.free_grad.iter().map(|g| g.length_squared()).sum();
    let mut share = [0.0; 4];
    for i in 0..n {
        let p = sys.particle_of[i] as usize;
        let g2 = s.free_grad[i].length_squared() / total;
        for (k, f) in [
            fl.non_manifold[p],
            fl.sliver[p],
            fl.boundary[p],
            s.held[i].is_some(),
        ]
        .into_iter()
        .enumerate()
        {
            if f {
                share[k] += g2;
            }
        }
    }
    let top: Vec<String> = order[..5]
        .iter()
        .map(|&i| {
            let p = sys.particle_of[i] as usize;
            let wt = sys.mass[i] * 9.81;
            format!(
                "{p}{}{}{}{}:{:.0}[i{:.0} s{:.0} b{:.0} h{:.0}]",
                if fl.non_manifold[p] { "N" } else { "" },
                if fl.sliver[p] { "S" } else { "" },
                if fl.boundary[p] { "B" } else { "" },
                if s.held[i].is_some() { "H" } else { "" },
                s.free_grad[i].length() / wt,
                t[i][0].length() / wt,
                t[i][1].length() / wt,
                t[i][2].length() / wt,
                t[i][3].length() / wt,
            )
        })
        .collect();
    if let Some(c) = &s.contact {
        for &i in &order[..3] {
            let q = c.colliders().shapes[0].contact(x[i], s.x0[i], 1.0);
            println!(
                "    particle {}: x {:.4} (moved {:.2e} m this step), collider distance {:?}, held {:?}",
                sys.particle_of[i],
                x[i],
                x[i].distance(s.x0[i]),
                q.map(|q| (q.distance, q.normal)),
                s.held[i]
            );
        }
    }
    println!(
        "  terms (RMS/weight): inertia {} springs {} bend {} held {} | share of ρ² N {:.2} S {:.2} B {:.2} H {:.2} | worst {}",
        norms[0], norms[1], norms[2], norms[3], share[0], share[1], share[2], share[3], top.join(" ")
    );
}
