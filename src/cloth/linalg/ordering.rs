//! Fill-reducing orders for the cloth solvers' sparse factors.

use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, SymmetricOrdering};
use faer::Side;

use super::factor::{faer_view, simplicial, upper_from_triplets};
use crate::error::{Error, Result};

/// Serialises calls into METIS (see [`nested_dissection`]).
static METIS_LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// A fill-reducing order for the n×n symmetric pattern given by `pairs` (plus the diagonal):
/// `order[new] = old`.
///
/// Two candidates, and the one whose Cholesky factor has fewer entries (as CHOLMOD chooses):
/// faer's approximate minimum degree, and METIS's multilevel nested dissection (`METIS_NodeND`,
/// default options: its fixed random seed makes the order the same on every run). Nested
/// dissection wins on garment-sized meshes (on the 8k-vertex skirt's Newton Hessian 21 % fewer
/// factor entries and 42 % fewer flops, docs/performance.md); minimum degree on small ones (the
/// 315-particle Fox cape).
///
/// # Errors
/// [`Error::Factorisation`] when either ordering fails (out of memory) or the graph is too large
/// for METIS's 32-bit indices.
pub fn fill_reducing_order(
    n: usize,
    pairs: impl Iterator<Item = (usize, usize)>,
) -> Result<Vec<u32>> {
    // Both directions of every edge, without self loops or duplicates (as METIS requires).
    let mut edges: Vec<(u32, u32)> = pairs
        .filter(|(a, b)| a != b)
        .flat_map(|(a, b)| [(a as u32, b as u32), (b as u32, a as u32)])
        .collect();
    edges.sort_unstable();
    edges.dedup();
    if n < 3 || edges.is_empty() {
        return Ok((0..n as u32).collect());
    }
    let mut triplets: Vec<(usize, usize, f64)> = (0..n).map(|i| (i, i, 1.0)).collect();
    triplets.extend(
        edges
            .iter()
            .filter(|(a, b)| a < b)
            .map(|&(a, b)| (a as usize, b as usize, 1.0)),
    );
    let upper = upper_from_triplets(n, &triplets);
    let pattern = faer_view(&upper).symbolic();
    let analyse = |ordering| {
        factorize_symbolic_cholesky(pattern, Side::Upper, ordering, simplicial())
            .map_err(|e| Error::Factorisation(format!("ordering: {e:?}")))
    };
    let amd = analyse(SymmetricOrdering::Amd)?;
    let amd_order: Vec<u32> = match amd.perm() {
        Some(perm) => perm.arrays().0.iter().map(|&i| i as u32).collect(),
        None => (0..n as u32).collect(),
    };
    let nd_order = nested_dissection(n, &edges)?;
    let forward: Vec<usize> = nd_order.iter().map(|&o| o as usize).collect();
    let mut inverse = vec![0usize; n];
    for (new, &old) in forward.iter().enumerate() {
        inverse[old] = new;
    }
    let nd = analyse(SymmetricOrdering::Custom(PermRef::new_checked(
        &forward, &inverse, n,
    )))?;
    Ok(if nd.len_val() < amd.len_val() {
        nd_order
    } else {
        amd_order
    })
}

/// METIS's nested-dissection order (`order[new] = old`) of the graph on n vertices whose
/// adjacency `edges` lists both directions of every edge, sorted, without self loops.
pub(super) fn nested_dissection(n: usize, edges: &[(u32, u32)]) -> Result<Vec<u32>> {
    let too_large =
        || Error::Factorisation(format!("ordering: {n} unknowns are too many for METIS"));
    let idx = |i: usize| metis_sys::idx_t::try_from(i).map_err(|_| too_large());
    let mut xadj = Vec::with_capacity(n + 1);
    let mut next = 0;
    for v in 0..n as u32 {
        xadj.push(idx(next)?);
        while next < edges.len() && edges[next].0 == v {
            next += 1;
        }
    }
    xadj.push(idx(next)?);
    let mut adjncy = edges
        .iter()
        .map(|&(_, b)| idx(b as usize))
        .collect::<Result<Vec<_>>>()?;
    let mut nvtxs = idx(n)?;
    let (mut perm, mut iperm) = (vec![0; n], vec![0; n]);
    // METIS seeds one process-wide random generator (GKlib's `mt` array) at the start of each
    // call and draws from it throughout: concurrent calls (a scene's jobs run in parallel) would
    // interleave their draws and make the order, hence the bake's roundoff, vary from run to run.
    // A poisoned lock only means another ordering panicked; the generator is reseeded anyway.
    let _serial = METIS_LOCK.lock().unwrap_or_else(|e| e.into_inner());
    // SAFETY: METIS_NodeND reads nvtxs, xadj (nvtxs + 1 entries) and adjncy (xadj[nvtxs] entries,
    // each in 0..nvtxs, symmetric, no self loops: built above) and writes nvtxs entries to perm
    // and iperm; null vertex weights and options select its defaults. It keeps no pointer.
    let status = unsafe {
        metis_sys::METIS_NodeND(
            &mut nvtxs,
            xadj.as_mut_ptr(),
            adjncy.as_mut_ptr(),
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            perm.as_mut_ptr(),
            iperm.as_mut_ptr(),
        )
    };
    if status != metis_sys::rstatus_et_METIS_OK {
        return Err(Error::Factorisation(format!(
            "ordering: METIS nested dissection failed (status {status})"
        )));
    }
    // perm[new] = old (METIS's manual: row i of the permuted matrix is row perm[i]).
    let mut seen = vec![false; n];
    let mut order = Vec::with_capacity(n);
    for &o in &perm {
        match usize::try_from(o)
            .ok()
            .filter(|&o| seen.get(o) == Some(&false))
        {
            Some(o) => {
                seen[o] = true;
                order.push(o as u32);
            }
            None => {
                return Err(Error::Factorisation(
                    "ordering: METIS returned an index twice or out of range".to_string(),
                ))
            }
        }
    }
    Ok(order)
}
