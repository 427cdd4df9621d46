//! The frame cache: every particle's position at every frame, as solvers produce it and writers
//! consume it.

use glam::{DVec3, Vec3};

/// Recorded particle positions for frames 0..=N.
///
/// Layout: frame-major, `positions[frame * particles + particle]`, metres, as `f32` (what the
/// exporters write).
#[derive(Debug, Clone, PartialEq)]
pub struct FrameCache {
    particles: usize,
    positions: Vec<Vec3>,
}

impl FrameCache {
    /// An empty cache for `particles` particles.
    pub fn new(particles: usize) -> Self {
        FrameCache {
            particles,
            positions: Vec::new(),
        }
    }

    /// Appends a frame.
    ///
    /// # Panics
    /// When `frame.len()` differs from the particle count.
    pub fn push(&mut self, frame: &[DVec3]) {
        assert_eq!(frame.len(), self.particles, "frame size");
        self.positions.extend(frame.iter().map(|p| p.as_vec3()));
    }

    /// Number of recorded frames (the initial state included).
    pub fn frame_count(&self) -> usize {
        self.positions
            .len()
            .checked_div(self.particles)
            .unwrap_or(0)
    }

    /// Number of particles per frame.
    pub fn particle_count(&self) -> usize {
        self.particles
    }

    /// Positions of frame `k`.
    ///
    /// # Panics
    /// When `k >= frame_count()`.
    pub fn frame(&self, k: usize) -> &[Vec3] {
        &self.positions[k * self.particles..(k + 1) * self.particles]
    }
}
