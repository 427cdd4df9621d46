//! Diagnostics for Newton on real garments, run by hand (feature `probe`):
//!
//! ```text
//! PROBE_MESH=dress_draped.obj PROBE_COLLIDER=mannequin.obj PROBE_STEPS=3 \
//!     cargo run --release --example newton_probe --features probe
//! ```
//!
//! `PROBE_MESH` and `PROBE_COLLIDER` are files in `meshes/garments/` (`PROBE_COLLIDER=none`: no
//! collider). Other knobs: `PROBE_PIN` (a `--pin` spec), `PROBE_SHAPE` (a `--collider` spec
//! instead of a mesh), `PROBE_JAM`, `PROBE_BEND_REST` (`flat` or `mesh`), `PROBE_SUBSTEPS`,
//! `PROBE_BEND`, `PROBE_THICKNESS`, `PROBE_FRICTION`, `PROBE_CAP` (Newton iterations per step,
//! default 50), `PROBE_SWEEPS`, `PROBE_TRANSLATE` (x,y,z in metres, as the garments bench raises
//! circle_skirt above the table), `PROBE_CONTACT` (`constraint` or `barrier`), `PROBE_DOUBLE`
//! (set: double-precision factors only); every step also prints the line search's step
//! lengths α.
//!
//! Prints the mesh's flaws, the springs' and bending stencils' stiffness spread, how many
//! particles start within the collision thickness, and per step the residual at every Newton
//! iterate, the gradient split into its terms with the particles carrying most of it, and the
//! largest stretch and compression.
//!
//! It uses the library's public API only: the job layer resolves the garment as a bake would
//! ([`prepare_cloth`]), and [`NewtonSolver::diagnostics`] shows the solver's working vectors.

use std::collections::BTreeMap;
use std::error::Error;
use std::path::PathBuf;

use scenebake::bake::cloth::{prepare_cloth, ClothJob, ClothSource};
use scenebake::cloth::collide::{ColliderSpec, ContactModel};
use scenebake::cloth::law::spring_gradient;
use scenebake::cloth::material::BendRest;
use scenebake::cloth::newton::DEFAULT_SWEEPS;
use scenebake::cloth::{BendingFactor, NewtonSolver, ReducedSystem, StepSolver};
use scenebake::glam::DVec3;
use scenebake::mesh::Mesh;

type Res<T> = Result<T, Box<dyn Error>>;

/// The knob `name` parsed, or `default` when it is unset or does not parse.
fn env<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The knob `name` parsed, `None` when it is unset; an error names it when it does not parse.
fn knob<T: std::str::FromStr>(name: &str) -> Res<Option<T>>
where
    T::Err: std::fmt::Display,
{
    match std::env::var(name) {
        Ok(v) => v
            .parse()
            .map(Some)
            .map_err(|e| format!("{name}={v:?}: {e}").into()),
        Err(_) => Ok(None),
    }
}

/// Per particle (model order): on a non-manifold edge, on an edge shorter than 2 mm, on the
/// boundary.
struct Flags {
    non_manifold: Vec<bool>,
    sliver: Vec<bool>,
    boundary: Vec<bool>,
}

fn flags(mesh: &Mesh) -> Flags {
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

fn main() -> Res<()> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("meshes/garments");
    let mesh: String = env("PROBE_MESH", "dress_draped.obj".to_string());
    let collider: String = env("PROBE_COLLIDER", "mannequin.obj".to_string());
    let steps: usize = env("PROBE_STEPS", 3);
    let cap: usize = env("PROBE_CAP", 50);
    let mut job = ClothJob::new(ClothSource::File(root.join(&mesh)), "unused.glb".into());
    if let Some(shape) = knob::<String>("PROBE_SHAPE")? {
        job.collider = vec![shape
            .parse()
            .map_err(|e| format!("PROBE_SHAPE={shape:?}: {e}"))?];
    } else if collider != "none" {
        job.collider = vec![ColliderSpec::mesh(root.join(&collider))];
    }
    if let Some(b) = knob("PROBE_BEND")? {
        job.bend = Some(b);
    }
    if let Some(t) = knob("PROBE_THICKNESS")? {
        job.thickness = Some(t);
    }
    if let Some(p) = knob::<String>("PROBE_PIN")? {
        job.pin = vec![p.parse().map_err(|e| format!("PROBE_PIN={p:?}: {e}"))?];
    }
    if let Some(t) = knob::<String>("PROBE_TRANSLATE")? {
        job.translate = Some(
            scenebake::spec::vec3_value(&t).map_err(|e| format!("PROBE_TRANSLATE={t:?}: {e}"))?,
        );
    }
    if let Some(n) = knob("PROBE_SUBSTEPS")? {
        job.substeps = n;
    }
    if let Some(r) = knob::<String>("PROBE_BEND_REST")? {
        job.bend_rest = Some(match r.as_str() {
            "flat" => BendRest::Flat,
            "mesh" => BendRest::Mesh,
            _ => return Err(format!("PROBE_BEND_REST is `flat` or `mesh`, not {r:?}").into()),
        });
    }
    if let Some(c) = knob::<String>("PROBE_CONTACT")? {
        job.contact = Some(match c.as_str() {
            "constraint" => ContactModel::Constraint,
            "barrier" => ContactModel::Barrier,
            _ => {
                return Err(format!("PROBE_CONTACT is `constraint` or `barrier`, not {c:?}").into())
            }
        });
    }
    if let Some(j) = knob("PROBE_JAM")? {
        job.jam_strain = Some(j);
    }
    job.frames = Some(steps);
    job.friction = env("PROBE_FRICTION", job.friction);
    let prepared = prepare_cloth(&job)?;
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
        BendingFactor::default().coupling(),
    )?;
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
    let mut solver = NewtonSolver::new(sys, params.tolerance, cap)?
        .single_precision(std::env::var("PROBE_DOUBLE").is_err())
        .with_sweeps(env("PROBE_SWEEPS", DEFAULT_SWEEPS))
        .with_colliders(colliders);
    solver.record_history(true);
    let mut v = vec![DVec3::ZERO; x.len()];
    for step in 1..=steps {
        let t0 = std::time::Instant::now();
        let stats = solver.step(&mut x, &mut v)?;
        let joined = |v: Option<&[f64]>, f: fn(&f64) -> String| {
            v.unwrap_or_default()
                .iter()
                .map(f)
                .collect::<Vec<_>>()
                .join(" ")
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
        let sys = solver.system();
        let sp = &sys.springs;
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
        let pof = |i: u32| sys.particle_of[i as usize];
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
    Ok(())
}

/// The gradient's terms at the end of a step: inertia, springs, bending, and what the colliders
/// hold (∇g less the free gradient), as RMS per particle relative to its weight, and the worst
/// particles with their flags (N non-manifold, S sliver, B boundary, H held).
fn report_terms(s: &NewtonSolver, x: &[DVec3], fl: &Flags) {
    let sys = s.system();
    let d = s.diagnostics();
    let n = x.len();
    let h = sys.params.time_step;
    let w = sys.inertia_scale() / (h * h);
    let mut t = vec![[DVec3::ZERO; 4]; n];
    for i in 0..n {
        t[i][0] = (x[i] - d.y[i]) * (w * sys.mass[i]);
        t[i][3] = d.grad[i] - d.free_grad[i];
    }
    let sp = &sys.springs;
    for k in 0..sp.a.len() {
        let (a, b) = (sp.a[k] as usize, sp.b[k] as usize);
        let f = spring_gradient(x[a] - x[b], sp.rest[k], sp.k[k], sp.kc[k], sys.jam_strain);
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
        d.free_grad[b]
            .length_squared()
            .total_cmp(&d.free_grad[a].length_squared())
    });
    let total: f64 = d.free_grad.iter().map(|g| g.length_squared()).sum();
    let mut share = [0.0; 4];
    for i in 0..n {
        let p = sys.particle_of[i] as usize;
        let g2 = d.free_grad[i].length_squared() / total;
        for (k, f) in [
            fl.non_manifold[p],
            fl.sliver[p],
            fl.boundary[p],
            d.held[i].is_some(),
        ]
        .into_iter()
        .enumerate()
        {
            if f {
                share[k] += g2;
            }
        }
    }
    let top: Vec<String> = order[..5.min(n)]
        .iter()
        .map(|&i| {
            let p = sys.particle_of[i] as usize;
            let wt = sys.mass[i] * 9.81;
            format!(
                "{p}{}{}{}{}:{:.0}[i{:.0} s{:.0} b{:.0} h{:.0}]",
                if fl.non_manifold[p] { "N" } else { "" },
                if fl.sliver[p] { "S" } else { "" },
                if fl.boundary[p] { "B" } else { "" },
                if d.held[i].is_some() { "H" } else { "" },
                d.free_grad[i].length() / wt,
                t[i][0].length() / wt,
                t[i][1].length() / wt,
                t[i][2].length() / wt,
                t[i][3].length() / wt,
            )
        })
        .collect();
    if let Some(c) = d.colliders {
        for &i in &order[..3.min(n)] {
            let q = c.shapes[0].contact(x[i], d.x0[i], 1.0);
            println!(
                "    particle {}: x {:.4} (moved {:.2e} m this step), collider distance {:?}, held {:?}",
                sys.particle_of[i],
                x[i],
                x[i].distance(d.x0[i]),
                q.map(|q| (q.distance, q.normal)),
                d.held[i]
            );
        }
    }
    println!(
        "  terms (RMS/weight): inertia {} springs {} bend {} held {} | share of ρ² N {:.2} S {:.2} B {:.2} H {:.2} | worst {}",
        norms[0], norms[1], norms[2], norms[3], share[0], share[1], share[2], share[3], top.join(" ")
    );
}
