//! Umbo displacement under static pressure (UDSP); docs/mechanics.md.
//!
//! Sign convention: p = P_ear canal − P_middle ear; p > 0 pushes the eardrum medially. The
//! umbo displacement u is measured along the medial axis (positive = medial), so u(p) has the
//! sign of p for a sound ear. The asymmetry ratio is |u(−4 kPa)| / |u(+4 kPa)|.
//!
//! Method: the pressure is a follower load on the lateral eardrum face (re-evaluated at every
//! iterate); each branch (p > 0, p < 0) starts at rest and is loaded incrementally through
//! its pressures (increments of at most `max_step_pa`), each increment solved to equilibrium
//! by Newton iterations on the corotational model (warped tangent, inversion guard;
//! `StaticSolver::solve_with_pressure`), the factorised tangent kept for the next iteration
//! while the residual halves (`reuse_tangent_below`). An increment whose Newton iterations fail is undone
//! and halved, down to `min_step_pa`; one that fails even then ends its branch: the curve
//! keeps the points before it and says where and why it stopped (`StaticCurve::failure`), and
//! the gates on the missing points fail. A registered model that cannot carry the load is a
//! finding of the check, not an error of the run. The equilibria do not depend on the
//! increments (the default atlas and the sample packages give the same umbo displacements to
//! 1 nm with 250, 500, 1000 and 2000 Pa increments).

use rayon::join;
use serde::{Deserialize, Serialize};

use super::boundary::{MechanicalSystem, Ossicles};
use super::error::MechanicsError;
use crate::fem::{FactorPrecision, PressureLoad, StaticLoads, StaticOptions, StaticSolver};
use crate::progress::{Reporter, Task};

/// The pressures of the gate (Pa): ±1, ±2, ±4 kPa.
pub const GATE_PRESSURES_PA: [f64; 6] = [-4000.0, -2000.0, -1000.0, 1000.0, 2000.0, 4000.0];

/// Default `UdspOptions::residual_tolerance`.
const RESIDUAL_TOLERANCE: f64 = 1e-3;

/// Default `UdspOptions::reuse_tangent_below`: on the sample packages' gate curves it halves
/// the factorisations (case-001: 49 → 23) for a few more iterations (BENCHMARKS.md); 0.3
/// keeps more factorisations, 0.7 and 0.9 hardly fewer for more iterations.
const REUSE_TANGENT_BELOW: f64 = 0.5;

/// Default `UdspOptions::anderson_depth`: on the default atlas's 33-point curve 285 → 221
/// Newton iterations (depths 3-8 give 218-221), on the sample packages' gate curves 51-59 →
/// 48-50, the umbo displacements within 3 nm (BENCHMARKS.md).
const ANDERSON_DEPTH: usize = 4;

/// What to compute.
#[derive(Debug, Clone, PartialEq)]
pub struct UdspOptions {
    /// Pressures (Pa), any order; 0 is always included.
    pub pressures_pa: Vec<f64>,
    /// Largest load increment (Pa).
    pub max_step_pa: f64,
    /// Smallest increment a failed one is halved down to before the branch stops (Pa).
    pub min_step_pa: f64,
    /// Convergence of each increment: largest nodal update (mm); 1e-5 mm is 0.05 % of the
    /// umbo displacement at 1 kPa.
    pub tolerance_mm: f64,
    /// Convergence of each increment, also: the out-of-balance force at most this fraction
    /// of the load (`StaticSolver::with_residual_tolerance`).
    pub residual_tolerance: f64,
    /// Newton iteration limit per increment.
    pub max_iterations: usize,
    /// Levenberg shift of the tangent (µN/mm, see `StaticOptions::tangent_shift`): a thin
    /// eardrum's out-of-plane tangent is nearly singular where it is not yet tensioned.
    pub tangent_shift: f64,
    /// Tangent reuse (`StaticOptions::reuse_tangent_below`): a Newton iteration whose
    /// residual fell to at most this fraction of the previous one keeps the last factorised
    /// tangent; 0 factorises at every iteration.
    pub reuse_tangent_below: f64,
    /// Anderson acceleration of the chord steps (`StaticOptions::anderson_depth`): past
    /// iterations mixed into each; 0 takes the plain steps.
    pub anderson_depth: usize,
    /// The ossicles' model (`Ossicles::Rigid`: `StaticSolver::with_rigid_bodies`).
    pub ossicles: Ossicles,
    /// The precision the tangent is factorised in (`StaticOptions::tangent_precision`). An
    /// increment that fails with a single-precision tangent is tried again, before it is
    /// halved, with every later factorisation of its branch in double precision (its first
    /// step may still take the last, single-precision, factor as a chord).
    pub tangent_precision: FactorPrecision,
}

impl Default for UdspOptions {
    /// −4000 … +4000 Pa every 250 Pa (33 pressures, containing ±1, ±2, ±4 kPa).
    fn default() -> Self {
        UdspOptions {
            pressures_pa: (-16..=16).map(|k| 250.0 * k as f64).collect(),
            max_step_pa: 2000.0,
            min_step_pa: 62.5,
            tolerance_mm: 1e-5,
            residual_tolerance: RESIDUAL_TOLERANCE,
            max_iterations: 200,
            tangent_shift: 100.0,
            reuse_tangent_below: REUSE_TANGENT_BELOW,
            anderson_depth: ANDERSON_DEPTH,
            ossicles: Ossicles::Elastic,
            tangent_precision: FactorPrecision::Double,
        }
    }
}

/// One point of the curve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct UdspPoint {
    pub pressure_pa: f64,
    /// Umbo displacement along the medial axis (mm, positive = medial).
    pub umbo_mm: f64,
    /// Newton iterations of the increments from the previous point to this one (an attempt
    /// that failed and was halved not counted).
    pub iterations: usize,
    /// |out-of-balance force| / |load| at this point's equilibrium (0 at rest).
    #[serde(default)]
    pub relative_residual: f64,
}

/// The umbo displacement curve, sorted by pressure.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StaticCurve {
    /// The ossicles' model the solves used.
    #[serde(default)]
    pub ossicles: Ossicles,
    pub points: Vec<UdspPoint>,
    /// Where and why loading stopped short (an increment without equilibrium), if it did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
    /// The pressures \[Pa\] at which a branch solved with a single-precision tangent
    /// (`UdspOptions::tangent_precision`) met an increment it could not bring to equilibrium
    /// and went on in double precision from there; empty where none did.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub double_precision_from_pa: Vec<f64>,
}

impl StaticCurve {
    /// Umbo displacement (mm) at `p` Pa, if computed.
    pub fn at(&self, p: f64) -> Option<f64> {
        self.points
            .iter()
            .find(|q| (q.pressure_pa - p).abs() < 1e-6)
            .map(|q| q.umbo_mm)
    }

    /// |u(−4 kPa)| / |u(+4 kPa)|.
    pub fn asymmetry(&self) -> Option<f64> {
        Some(self.at(-4000.0)?.abs() / self.at(4000.0)?.abs())
    }

    /// Whether u strictly increases with p (a monotonic, sign-preserving response).
    pub fn monotonic(&self) -> bool {
        self.points.windows(2).all(|w| w[1].umbo_mm > w[0].umbo_mm)
            && self.points.iter().all(|q| q.pressure_pa * q.umbo_mm >= 0.0)
    }

    /// The umbo's incremental compliance du/dp (mm/Pa) at `p` Pa: the slope at `p` of the
    /// polynomial through the five computed points nearest it (on the default 250 Pa sweep
    /// within 0.1 % of equilibria solved 25 Pa either side; docs/mechanics.md, "Evidence").
    /// `None` where the curve has fewer points or one of the five lies over 750 Pa away.
    /// The linearised response to a small sound about the static equilibrium at `p` has this
    /// compliance as its low-frequency limit.
    pub fn compliance_at(&self, p: f64) -> Option<f64> {
        const POINTS: usize = 5;
        const REACH_PA: f64 = 750.0;
        let mut near: Vec<&UdspPoint> = self.points.iter().collect();
        near.sort_by(|a, b| {
            (a.pressure_pa - p)
                .abs()
                .total_cmp(&(b.pressure_pa - p).abs())
        });
        near.truncate(POINTS);
        if near.len() < POINTS || near.iter().any(|q| (q.pressure_pa - p).abs() > REACH_PA) {
            return None;
        }
        // d/dp of the Lagrange polynomial: Σ_j u_j L_j'(p), L_j' = Σ_{m≠j} 1/(p_j − p_m)
        // Π_{l≠j,m} (p − p_l)/(p_j − p_l)
        let x: Vec<f64> = near.iter().map(|q| q.pressure_pa).collect();
        let slope = (0..POINTS)
            .map(|j| {
                let basis_slope: f64 = (0..POINTS)
                    .filter(|&m| m != j)
                    .map(|m| {
                        (0..POINTS)
                            .filter(|&l| l != j && l != m)
                            .map(|l| (p - x[l]) / (x[j] - x[l]))
                            .product::<f64>()
                            / (x[j] - x[m])
                    })
                    .sum();
                near[j].umbo_mm * basis_slope
            })
            .sum::<f64>();
        slope.is_finite().then_some(slope)
    }
}

/// The static pressure curve of `system`; the two branches are solved in parallel, each
/// pressure reached reported to `progress`.
pub fn static_pressure_curve(
    system: &MechanicalSystem,
    options: &UdspOptions,
    progress: &dyn Reporter,
) -> Result<StaticCurve, MechanicsError> {
    StaticCurveSolver::new(system, options)?.solve(progress)
}

/// The static curve's solvers before any load: the options checked, the tangent's pattern,
/// the rigid reduction's plan and the symbolic factorisation built, and the tangent at rest
/// factorised and copied for the second branch (on a package about a sixth of the curve's
/// work, all of it serial), so that a caller can build them beside other work:
/// `validate::mechanics` does it while the transfer function builds its own solver.
pub struct StaticCurveSolver<'s> {
    system: &'s MechanicalSystem,
    options: &'s UdspOptions,
    /// One solver per branch (p < 0, p > 0): the second a copy of the first, sharing its
    /// pattern and symbolic analysis.
    solvers: [StaticSolver<'s>; 2],
}

impl<'s> StaticCurveSolver<'s> {
    /// Checks `options` and builds the solver of `system`'s static curve.
    pub fn new(
        system: &'s MechanicalSystem,
        options: &'s UdspOptions,
    ) -> Result<Self, MechanicsError> {
        check(options)?;
        let solver = match options.ossicles {
            Ossicles::Elastic => StaticSolver::new(&system.model, system.fixed.clone()),
            Ossicles::Rigid => StaticSolver::with_rigid_bodies(
                &system.model,
                system.fixed.clone(),
                &system.ossicles,
            ),
        };
        let mut solver = solver
            .and_then(|s| s.with_residual_tolerance(options.residual_tolerance))
            .map_err(MechanicsError::solve("static solver"))?;
        // both branches start with the tangent at rest (no stress yet, so the same for both
        // signs): factorised once, here. A rest state that cannot be factorised is left to
        // the branches: each meets it again in its first increment and records it as where
        // its loading stopped, a finding of the check and not an error of the run.
        let mut rest = system.model.rest_positions().to_vec();
        let _ = solver.factorise_ahead(&mut rest, &loads(system), true, &static_options(options));
        Ok(StaticCurveSolver {
            system,
            options,
            solvers: [solver.clone(), solver],
        })
    }

    /// Solves the two branches in parallel, each pressure reached reported to `progress`.
    pub fn solve(self, progress: &dyn Reporter) -> Result<StaticCurve, MechanicsError> {
        let StaticCurveSolver {
            system,
            options,
            solvers: [negative, positive],
        } = self;
        let branches: [Vec<f64>; 2] = [-1.0, 1.0].map(|sign| {
            let mut ps: Vec<f64> = options
                .pressures_pa
                .iter()
                .copied()
                .filter(|p| p * sign > 0.0)
                .collect();
            ps.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
            ps.dedup();
            ps
        });
        let task = progress.task("UDSP", branches.iter().map(|b| b.len() as u64).sum());
        let (neg, pos) = join(
            || solve_branch(system, negative, &branches[0], options, task.as_ref()),
            || solve_branch(system, positive, &branches[1], options, task.as_ref()),
        );
        let (neg, pos) = (neg?, pos?);
        let mut points = neg.points;
        points.push(UdspPoint {
            pressure_pa: 0.0,
            umbo_mm: 0.0,
            iterations: 0,
            relative_residual: 0.0,
        });
        points.extend(pos.points);
        points.sort_by(|a, b| a.pressure_pa.total_cmp(&b.pressure_pa));
        task.finish(&format!("{} static pressures solved", points.len() - 1));
        let failures: Vec<String> = neg.failure.into_iter().chain(pos.failure).collect();
        Ok(StaticCurve {
            ossicles: options.ossicles,
            points,
            failure: (!failures.is_empty()).then(|| failures.join("; ")),
            double_precision_from_pa: neg
                .double_from_pa
                .into_iter()
                .chain(pos.double_from_pa)
                .collect(),
        })
    }
}

/// Refuses options no curve can be solved with.
fn check(options: &UdspOptions) -> Result<(), MechanicsError> {
    for (what, v) in [
        ("largest pressure step (Pa)", options.max_step_pa),
        ("smallest pressure step (Pa)", options.min_step_pa),
        ("static tolerance (mm)", options.tolerance_mm),
        ("static residual tolerance", options.residual_tolerance),
        ("tangent shift + 1 (µN/mm)", options.tangent_shift + 1.0),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(MechanicsError::InvalidOption {
                what,
                value: v,
                expected: "finite and > 0",
            });
        }
    }
    if !(0.0..1.0).contains(&options.reuse_tangent_below) {
        return Err(MechanicsError::InvalidOption {
            what: "tangent reuse (residual ratio)",
            value: options.reuse_tangent_below,
            expected: "in [0, 1)",
        });
    }
    if let Some(p) = options.pressures_pa.iter().find(|p| !p.is_finite()) {
        return Err(MechanicsError::InvalidOption {
            what: "static pressure (Pa)",
            value: *p,
            expected: "finite",
        });
    }
    Ok(())
}

/// The loads besides the pressure: the system's springs.
fn loads(system: &MechanicalSystem) -> StaticLoads<'_> {
    StaticLoads {
        springs: &system.springs,
        nodal_forces: None,
    }
}

/// The solver's controls for each increment.
fn static_options(options: &UdspOptions) -> StaticOptions {
    StaticOptions {
        tolerance_mm: options.tolerance_mm,
        max_iterations: options.max_iterations,
        tangent_shift: options.tangent_shift,
        reuse_tangent_below: options.reuse_tangent_below,
        anderson_depth: options.anderson_depth,
        tangent_precision: options.tangent_precision,
        ..StaticOptions::default()
    }
}

/// One branch of the curve, loaded from rest.
struct Branch {
    /// The points reached.
    points: Vec<UdspPoint>,
    /// Why the branch stopped short, if it did.
    failure: Option<String>,
    /// The pressure of the increment from which it went on in double precision, if it did.
    double_from_pa: Option<f64>,
}

/// Loads from rest through `pressures` (one sign, increasing magnitude), each point reached
/// reported to `task`.
fn solve_branch(
    system: &MechanicalSystem,
    mut solver: StaticSolver<'_>,
    pressures: &[f64],
    options: &UdspOptions,
    task: &dyn Task,
) -> Result<Branch, MechanicsError> {
    let rest = system.model.rest_positions();
    let mut x = rest.to_vec();
    let loads = loads(system);
    let mut static_options = static_options(options);
    let u0 = system.umbo.position(rest);
    let mut out = Vec::with_capacity(pressures.len());
    let mut current = 0.0f64;
    let mut step = options.max_step_pa;
    let mut before = x.clone();
    let mut double_from_pa = None;
    for &target in pressures {
        let mut iterations = 0;
        let mut relative_residual = 0.0;
        while current != target {
            let p = if (target - current).abs() <= step {
                target
            } else {
                current + step * (target - current).signum()
            };
            let load = PressureLoad {
                triangles: &system.eardrum,
                // the lateral normals point into the canal: canal pressure pushes against them
                pressure: -p,
            };
            before.copy_from_slice(&x);
            match solver.solve_with_pressure(&mut x, &loads, &load, &static_options) {
                Ok(report) => {
                    iterations += report.iterations;
                    relative_residual = report.relative_residual;
                    current = p;
                    step = (2.0 * step).min(options.max_step_pa);
                }
                Err(_) if static_options.tangent_precision == FactorPrecision::Single => {
                    x.copy_from_slice(&before);
                    static_options.tangent_precision = FactorPrecision::Double;
                    double_from_pa = Some(p);
                }
                Err(_) if step / 2.0 >= options.min_step_pa => {
                    x.copy_from_slice(&before);
                    step /= 2.0;
                }
                Err(e) => {
                    return Ok(Branch {
                        points: out,
                        failure: Some(format!("static pressure {p:.0} Pa: {e}")),
                        double_from_pa,
                    });
                }
            }
        }
        out.push(UdspPoint {
            pressure_pa: target,
            umbo_mm: (system.umbo.position(&x) - u0).dot(&system.medial),
            iterations,
            relative_residual,
        });
        task.inc(1);
    }
    Ok(Branch {
        points: out,
        failure: None,
        double_from_pa,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// u = a·tanh(p/b) sampled at `pressures`.
    fn tanh_curve(pressures: impl Iterator<Item = f64>) -> StaticCurve {
        StaticCurve {
            points: pressures
                .map(|p| UdspPoint {
                    pressure_pa: p,
                    umbo_mm: 0.2 * (p / 1500.0).tanh(),
                    iterations: 1,
                    relative_residual: 0.0,
                })
                .collect(),
            ..StaticCurve::default()
        }
    }

    #[test]
    fn compliance_is_the_slope_of_the_curve_between_its_points_and_refused_where_it_is_sparse() {
        let curve = tanh_curve((-16..=16).map(|k| 250.0 * k as f64));
        // d/dp a·tanh(p/b) = (a/b)·sech²(p/b)
        for p in [0.0_f64, 980.665, -1961.33, 2941.995, 3600.0] {
            let exact = 0.2 / 1500.0 / (p / 1500.0).cosh().powi(2);
            let c = curve.compliance_at(p).unwrap();
            assert!(
                (c / exact - 1.0).abs() < 1e-3,
                "{p} Pa: {c} against {exact}"
            );
        }
        // near the curve's end the nearest five points reach too far
        assert!(curve.compliance_at(4800.0).is_none());
        let sparse = tanh_curve((-4..=4).map(|k| 1000.0 * k as f64));
        assert!(sparse.compliance_at(500.0).is_none());
        assert!(
            tanh_curve([0.0, 250.0].into_iter())
                .compliance_at(0.0)
                .is_none()
        );
    }
}
