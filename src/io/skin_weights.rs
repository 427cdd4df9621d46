//! Skin weights: reading every WEIGHTS_n set of a primitive, checking their sums, and
//! renormalising them.
//!
//! glTF requires each vertex's skin weights (over all WEIGHTS_n sets) to sum to 1; some published
//! rigs do not (a Khronos sample's sums run from 0.18 to 0.99), which the validator reports as
//! one error per vertex and viewers handle each their own way (three.js uses them as they are,
//! shrinking the mesh towards the origin). A rig loaded for an IK bake gets its weights divided
//! by their sum; a vertex whose weights are all zero gets its first joint with weight 1.

use gltf_json as json;
use json::validation::{Checked::Valid, USize64};

/// Largest |sum − 1| accepted as normalised (the validator's float tolerance is tighter per
/// component; this is what a renormalisation in `f32` leaves).
pub const SUM_TOLERANCE: f32 = 2e-3;

/// Weight sums of one primitive.
#[derive(Debug, Clone, PartialEq)]
pub struct WeightSums {
    /// `meshes[m].primitives[p]`.
    pub mesh: usize,
    /// Primitive index.
    pub primitive: usize,
    /// Vertices.
    pub vertices: usize,
    /// Vertices whose sum is off 1 by more than [`SUM_TOLERANCE`].
    pub off: usize,
    /// Smallest and largest sum over the vertices that are off (0, 0 when none).
    pub range: (f32, f32),
}

/// What [`renormalise`] changed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Renormalised {
    /// Vertices whose weights were rescaled (summed over primitives; a shared accessor counts
    /// once).
    pub vertices: usize,
    /// Vertices with all-zero weights given their first joint.
    pub zero: usize,
    /// Smallest and largest sum found among the rescaled vertices.
    pub range: (f32, f32),
}

/// Reads a dense float or normalised-integer accessor of `components` per element from the
/// single merged buffer `bin`; `None` for sparse, out-of-range or unsupported accessors.
fn read_accessor(
    root: &json::Root,
    bin: &[u8],
    index: usize,
    components: usize,
) -> Option<Vec<f32>> {
    let acc = root.accessors.get(index)?;
    if acc.sparse.is_some() {
        return None;
    }
    let view = root.buffer_views.get(acc.buffer_view?.value())?;
    let Valid(ct) = acc.component_type else {
        return None;
    };
    let size = match ct.0 {
        json::accessor::ComponentType::F32 => 4,
        json::accessor::ComponentType::U16 => 2,
        json::accessor::ComponentType::U8 => 1,
        _ => return None,
    };
    let stride = view.byte_stride.map_or(size * components, |s| s.0);
    let start =
        view.byte_offset.map_or(0, |o| o.0 as usize) + acc.byte_offset.map_or(0, |o| o.0 as usize);
    let count = acc.count.0 as usize;
    let mut out = Vec::with_capacity(count * components);
    for i in 0..count {
        for c in 0..components {
            let at = start + i * stride + c * size;
            let bytes = bin.get(at..at + size)?;
            out.push(match ct.0 {
                json::accessor::ComponentType::F32 => f32::from_le_bytes(bytes.try_into().ok()?),
                json::accessor::ComponentType::U16 => {
                    f32::from(u16::from_le_bytes(bytes.try_into().ok()?)) / 65535.0
                }
                _ => f32::from(bytes[0]) / 255.0,
            });
        }
    }
    Some(out)
}

/// The WEIGHTS_n accessor indices of a primitive, in set order.
fn weight_sets(prim: &json::mesh::Primitive) -> Vec<usize> {
    let mut sets: Vec<(u32, usize)> = prim
        .attributes
        .iter()
        .filter_map(|(k, v)| match k {
            Valid(json::mesh::Semantic::Weights(n)) => Some((*n, v.value())),
            _ => None,
        })
        .collect();
    sets.sort();
    sets.into_iter().map(|(_, a)| a).collect()
}

/// Per-vertex weight sums over all sets, or `None` when a set cannot be read.
fn sums(root: &json::Root, bin: &[u8], sets: &[usize]) -> Option<(usize, Vec<Vec<f32>>, Vec<f32>)> {
    let data: Vec<Vec<f32>> = sets
        .iter()
        .map(|&a| read_accessor(root, bin, a, 4))
        .collect::<Option<_>>()?;
    let n = data.first().map_or(0, |d| d.len() / 4);
    if data.iter().any(|d| d.len() != n * 4) {
        return None;
    }
    let s = (0..n)
        .map(|v| {
            data.iter()
                .map(|d| d[v * 4..v * 4 + 4].iter().sum::<f32>())
                .sum()
        })
        .collect();
    Some((n, data, s))
}

/// Weight sums of every skinned primitive (one with WEIGHTS_0) that can be read.
pub fn check_sums(root: &json::Root, bin: &[u8]) -> Vec<WeightSums> {
    let mut out = Vec::new();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let sets = weight_sets(prim);
            if sets.is_empty() {
                continue;
            }
            let Some((n, _, s)) = sums(root, bin, &sets) else {
                continue;
            };
            let off: Vec<f32> = s
                .iter()
                .copied()
                .filter(|x| (x - 1.0).abs() > SUM_TOLERANCE)
                .collect();
            out.push(WeightSums {
                mesh: m,
                primitive: p,
                vertices: n,
                off: off.len(),
                range: off.iter().fold(
                    (if off.is_empty() { 0.0 } else { f32::MAX }, 0.0),
                    |(lo, hi), &x| (lo.min(x), hi.max(x)),
                ),
            });
        }
    }
    out
}

/// Rescales every skinned primitive's weights whose sums are off 1 (by more than 1e-6) so they
/// sum to 1, writing new float WEIGHTS_n accessors into `bin` (the old ones stay, unused). All
/// buffer views must refer to buffer 0, whose bytes are `bin`.
pub fn renormalise(root: &mut json::Root, bin: &mut Vec<u8>) -> Renormalised {
    let mut done = Renormalised {
        range: (f32::MAX, 0.0),
        ..Default::default()
    };
    // Accessor sets already rewritten: old indices -> new indices.
    let mut rewritten: Vec<(Vec<usize>, Vec<usize>)> = Vec::new();
    for m in 0..root.meshes.len() {
        for p in 0..root.meshes[m].primitives.len() {
            let sets = weight_sets(&root.meshes[m].primitives[p]);
            if sets.is_empty() {
                continue;
            }
            let new = match rewritten.iter().find(|(old, _)| *old == sets) {
                Some((_, new)) => Some(new.clone()),
                None => {
                    let Some((n, mut data, s)) = sums(root, bin, &sets) else {
                        continue;
                    };
                    let mut changed = 0;
                    for v in 0..n {
                        let sum = s[v];
                        if (sum - 1.0).abs() <= 1e-6 {
                            continue;
                        }
                        changed += 1;
                        if sum > 0.0 {
                            done.range = (done.range.0.min(sum), done.range.1.max(sum));
                            let sum = f64::from(sum);
                            for d in &mut data {
                                for w in &mut d[v * 4..v * 4 + 4] {
                                    *w = (f64::from(*w) / sum) as f32;
                                }
                            }
                            exact_sum(&mut data, v);
                        } else {
                            done.zero += 1;
                            for (k, d) in data.iter_mut().enumerate() {
                                d[v * 4..v * 4 + 4].copy_from_slice(&if k == 0 {
                                    [1.0, 0.0, 0.0, 0.0]
                                } else {
                                    [0.0; 4]
                                });
                            }
                        }
                    }
                    if changed == 0 {
                        rewritten.push((sets.clone(), sets.clone()));
                        None
                    } else {
                        done.vertices += changed;
                        let new: Vec<usize> =
                            data.iter().map(|d| push_weights(root, bin, d)).collect();
                        rewritten.push((sets.clone(), new.clone()));
                        Some(new)
                    }
                }
            };
            if let Some(new) = new {
                let prim = &mut root.meshes[m].primitives[p];
                for (set, &acc) in new.iter().enumerate() {
                    prim.attributes.insert(
                        Valid(json::mesh::Semantic::Weights(set as u32)),
                        json::Index::new(acc as u32),
                    );
                }
            }
        }
    }
    if done.vertices == 0 {
        done.range = (0.0, 0.0);
    }
    done
}

/// Makes vertex `v`'s weights sum to 1 as exactly as `f32` allows (summed in `f64`, as the
/// validator does): the largest weight takes 1 minus the others.
fn exact_sum(data: &mut [Vec<f32>], v: usize) {
    let mut largest = (0, 0, f32::MIN);
    for (k, d) in data.iter().enumerate() {
        for c in 0..4 {
            if d[v * 4 + c] > largest.2 {
                largest = (k, c, d[v * 4 + c]);
            }
        }
    }
    let rest: f64 = data
        .iter()
        .enumerate()
        .flat_map(|(k, d)| (0..4).map(move |c| (k, c, d[v * 4 + c])))
        .filter(|&(k, c, _)| (k, c) != (largest.0, largest.1))
        .map(|(_, _, w)| f64::from(w))
        .sum();
    data[largest.0][v * 4 + largest.1] = (1.0 - rest) as f32;
}

/// Appends a float VEC4 accessor (its own 4-byte-aligned view) and returns its index.
fn push_weights(root: &mut json::Root, bin: &mut Vec<u8>, data: &[f32]) -> usize {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let offset = bin.len();
    bin.extend(data.iter().flat_map(|x| x.to_le_bytes()));
    let view = root.push(json::buffer::View {
        buffer: json::Index::new(0),
        byte_length: USize64::from(data.len() * 4),
        byte_offset: Some(USize64::from(offset)),
        byte_stride: None,
        name: None,
        target: Some(Valid(json::buffer::Target::ArrayBuffer)),
        extensions: None,
        extras: Default::default(),
    });
    let acc = root.push(json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(data.len() / 4),
        component_type: Valid(json::accessor::GenericComponentType(
            json::accessor::ComponentType::F32,
        )),
        extensions: None,
        extras: Default::default(),
        type_: Valid(json::accessor::Type::Vec4),
        min: None,
        max: None,
        name: None,
        normalized: false,
        sparse: None,
    });
    acc.value()
}
