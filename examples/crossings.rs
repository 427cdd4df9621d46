//! Counts the crossing triangle pairs of a point cache, frame by frame: the cloth with itself and
//! with a body given as an OBJ sequence, by the exact test every bake's report uses
//! (`scenebake::measure`). It reads any PC2 in the OBJ's vertex order, so it measures another
//! solver's result (`benches/blender_cloth.py --pc2-out`) the way a bake measures its own.
//!
//! ```text
//! cargo run --release --example crossings -- CLOTH.obj CACHE.pc2 [BODY%d.obj BODY_FPS FPS]
//! ```
//!
//! The cloth's triangles come from the OBJ's `f` lines (fanned), its vertices welded where
//! their positions in the OBJ are equal (so triangles on either side of a UV seam are
//! neighbours, as in a bake's model); the body at cache frame k is the sequence at k / FPS
//! seconds, linear between its frames (as a bake moves it). Prints `frame self body` per frame
//! and the largest counts.

use std::collections::HashMap;
use std::path::Path;

use scenebake::glam::DVec3;
use scenebake::measure::{crossings_between, self_crossings, Soup};

type Failure = Box<dyn std::error::Error>;

/// The OBJ's `v` lines and its faces fanned into triangles over welded vertices.
fn read_obj(path: &Path) -> Result<(usize, Vec<[u32; 3]>), Failure> {
    let text = std::fs::read_to_string(path)?;
    let mut positions: Vec<[u64; 3]> = Vec::new();
    let mut triangles = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let p: Vec<f64> = words.take(3).map(str::parse).collect::<Result<_, _>>()?;
                if p.len() != 3 {
                    return Err(format!(
                        "{}:{}: a `v` line needs 3 numbers",
                        path.display(),
                        n + 1
                    )
                    .into());
                }
                positions.push([p[0].to_bits(), p[1].to_bits(), p[2].to_bits()]);
            }
            Some("f") => {
                let corners: Vec<u32> = words
                    .map(|w| {
                        let i: i64 = w.split('/').next().unwrap_or("").parse()?;
                        Ok(if i > 0 {
                            i - 1
                        } else {
                            positions.len() as i64 + i
                        } as u32)
                    })
                    .collect::<Result<_, std::num::ParseIntError>>()?;
                for k in 1..corners.len().saturating_sub(1) {
                    triangles.push([corners[0], corners[k], corners[k + 1]]);
                }
            }
            _ => {}
        }
    }
    let mut first: HashMap<[u64; 3], u32> = HashMap::new();
    let weld: Vec<u32> = (0..positions.len() as u32)
        .map(|i| *first.entry(positions[i as usize]).or_insert(i))
        .collect();
    let triangles = triangles
        .into_iter()
        .map(|t: [u32; 3]| t.map(|i| weld[i as usize]))
        .collect();
    Ok((positions.len(), triangles))
}

/// A PC2 file's samples (little-endian: signature, version, points, start, rate, samples).
fn read_pc2(path: &Path) -> Result<Vec<Vec<DVec3>>, Failure> {
    let b = std::fs::read(path)?;
    if b.len() < 32 || &b[..12] != b"POINTCACHE2\0" {
        return Err(format!("{}: not a PC2 file", path.display()).into());
    }
    let int = |at: usize| i32::from_le_bytes(b[at..at + 4].try_into().unwrap()) as usize;
    let (points, samples) = (int(16), int(28));
    if b.len() != 32 + 12 * points * samples {
        return Err(format!(
            "{}: {points} points × {samples} samples do not fill it",
            path.display()
        )
        .into());
    }
    let float = |at: usize| f64::from(f32::from_le_bytes(b[at..at + 4].try_into().unwrap()));
    Ok((0..samples)
        .map(|s| {
            (0..points)
                .map(|p| {
                    let o = 32 + 12 * (s * points + p);
                    DVec3::new(float(o), float(o + 4), float(o + 8))
                })
                .collect()
        })
        .collect())
}

fn main() -> Result<(), Failure> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() != 2 && args.len() != 5 {
        return Err("usage: crossings CLOTH.obj CACHE.pc2 [BODY%d.obj BODY_FPS FPS]".into());
    }
    let (points, triangles) = read_obj(Path::new(&args[0]))?;
    let frames = read_pc2(Path::new(&args[1]))?;
    if frames.first().is_some_and(|f| f.len() != points) {
        return Err(format!(
            "{} has {points} vertices, the cache {}",
            args[0],
            frames[0].len()
        )
        .into());
    }
    let body = match &args[2..] {
        [pattern, body_fps, _] => Some(scenebake::io::sequence::load_obj_sequence(
            Path::new(pattern),
            body_fps.parse()?,
            None,
        )?),
        _ => None,
    };
    let fps: f64 = args.get(4).map_or(Ok(1.0), |f| f.parse())?;
    let (mut most_self, mut most_body) = ((0, 0), (0, 0));
    for (k, x) in frames.iter().enumerate() {
        let cloth = Soup {
            positions: x,
            triangles: &triangles,
        };
        let own = self_crossings(cloth);
        let with_body = body.as_ref().map_or(0, |b| {
            let at = b.at(k as f64 / fps);
            crossings_between(
                cloth,
                Soup {
                    positions: &at,
                    triangles: &b.mesh.triangles,
                },
            )
        });
        println!("{k} {own} {with_body}");
        most_self = most_self.max((own, k));
        most_body = most_body.max((with_body, k));
    }
    println!(
        "most: {} pairs with itself (frame {}), {} with the body (frame {})",
        most_self.0, most_self.1, most_body.0, most_body.1
    );
    Ok(())
}
