//! A body given as a mesh sequence: the same vertices and faces in every frame, the positions of
//! each frame, and the rate the frames play at.

use std::path::PathBuf;

use glam::DVec3;

use crate::mesh::Mesh;

/// A mesh sequence (an animated body read frame by frame).
#[derive(Debug, Clone)]
pub struct MeshSequence {
    /// The first frame as a mesh: its triangles and render surface (every frame shares them).
    pub mesh: Mesh,
    /// The positions of the mesh's particles at every frame, frame 0 first.
    pub frames: Vec<Vec<DVec3>>,
    /// Frames per second: frame i plays at i / fps seconds.
    pub fps: f64,
    /// The file of every frame, in order.
    pub files: Vec<PathBuf>,
    /// The number in the first file's name.
    pub first_number: u64,
}

impl MeshSequence {
    /// Seconds from the first frame to the last.
    pub fn duration(&self) -> f64 {
        self.frames.len().saturating_sub(1) as f64 / self.fps
    }

    /// The positions at `t` seconds: linear between the two frames around it, held at the first
    /// frame before 0 and at the last one after [`MeshSequence::duration`].
    pub fn at(&self, t: f64) -> Vec<DVec3> {
        let last = self.frames.len() - 1;
        let f = (t * self.fps).clamp(0.0, last as f64);
        let i = (f.floor() as usize).min(last);
        let s = f - i as f64;
        if i == last || s == 0.0 {
            return self.frames[i].clone();
        }
        self.frames[i]
            .iter()
            .zip(&self.frames[i + 1])
            .map(|(a, b)| a.lerp(*b, s))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_between_frames_are_linear_and_held_at_the_ends() {
        let mesh = Mesh::from_triangles("t".into(), vec![DVec3::ZERO; 3], vec![[0, 1, 2]]);
        let frame = |y: f64| vec![DVec3::new(0.0, y, 0.0); 3];
        let s = MeshSequence {
            mesh,
            frames: vec![frame(0.0), frame(1.0), frame(3.0)],
            fps: 4.0,
            files: Vec::new(),
            first_number: 0,
        };
        assert_eq!(s.duration(), 0.5);
        assert_eq!(s.at(-1.0)[0].y, 0.0);
        assert!((s.at(0.125)[1].y - 0.5).abs() < 1e-12);
        assert!((s.at(0.375)[2].y - 2.0).abs() < 1e-12);
        assert_eq!(s.at(0.25)[0].y, 1.0);
        assert_eq!(s.at(9.0)[0].y, 3.0);
    }
}
