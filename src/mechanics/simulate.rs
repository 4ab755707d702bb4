//! Real-time stepping of the mechanical system: linearised backward Euler, one solve per step
//! (SOFA EulerImplicitSolver; docs/fem.md):
//!
//! (M(1 + hα) + hC + h(h + β)K_T) v' = M v + h (f_el(x) + f_springs(x) + f_ext(x)),
//! x' = x + h v',
//!
//! with K_T the warped tangent R K Rᵀ plus the membranes' tensile stress stiffness plus the
//! annular-ligament springs at the current positions, and C the cochlear dashpots along the
//! footplate normal. The linear system is solved by conjugate
//! gradients on the *current* matrix, applied matrix-free element by element
//! (`StepOperator`: the matrix is not assembled for the products), preconditioned with a
//! Cholesky factor of the same matrix from an earlier step (the study's scheme: Courtecuisse
//! et al. 2010, SOFA's PCGLinearSolver + AsyncSparseLDLSolver; the symbolic analysis is done
//! once, the matrix is assembled only to be factorised). So every step solves the current
//! system to the CG tolerance (relative residual 1e-6); the stale factor only costs
//! iterations, and when it is too stale (more than 2 iterations) it is refreshed at once and
//! the step solved with it, as it is every `refactor_every` steps; the next step then
//! refreshes it before solving (while a load sets in, a factor one step old is stale again:
//! this saves two solves and a product in each of those steps). (The matrix cannot simply
//! be frozen at the rest shape: the eardrum is a membrane whose out-of-plane stiffness comes
//! from its tension under load, absent at rest, and such an iteration diverges.) The ear-canal
//! pressure is a follower load on the lateral eardrum face, evaluated at the current positions.

use nalgebra::{Point3, Vector3};
use serde::Serialize;

use super::boundary::MechanicalSystem;
use super::error::MechanicsError;
use crate::fem::{
    CorotationalState, Dashpot, Pcg, PressureLoad, SparseCholesky, SparsePattern, StepOperator,
};

/// Relative residual of each step's conjugate-gradient solve.
const CG_TOLERANCE: f64 = 1e-6;
/// Conjugate-gradient iterations allowed with a stale preconditioner before it is refreshed
/// (the step is then solved with the fresh factor). A refresh (assembly and numeric
/// factorisation) costs about as much as 15 iterations, and a factor that needs more than 2
/// iterations is stale enough that its replacement brings the following steps back to one
/// iteration: measured on the default atlas (300 steps under 1 kPa, the eardrum a bending
/// shell), a limit of 2 gives 1.1 iterations and 16 refreshes, a limit of 4 gives 2.2
/// iterations and 9 refreshes and costs 20-40 % more time (BENCHMARKS.md).
const CG_MAX_ITERATIONS: usize = 2;

/// What to simulate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulationOptions {
    pub steps: usize,
    /// Time step (s); the study used 0.04.
    pub dt: f64,
    /// Ear-canal pressure (Pa, + pushes medially), applied from the first step.
    pub pressure_pa: f64,
    /// A point force on the umbo along the medial axis (µN), applied from the first step.
    pub umbo_force_un: f64,
    /// Refresh the preconditioner (factorise the current step matrix) every this many steps.
    pub refactor_every: usize,
}

impl Default for SimulationOptions {
    fn default() -> Self {
        SimulationOptions {
            steps: 250,
            dt: 0.04,
            pressure_pa: 1000.0,
            umbo_force_un: 0.0,
            refactor_every: 1000,
        }
    }
}

/// The umbo at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Frame {
    pub time_s: f64,
    /// Displacement along the medial axis (mm, + = medial).
    pub umbo_medial_mm: f64,
    /// Position (mm).
    pub umbo: [f64; 3],
}

/// A simulated trajectory and its speed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Simulation {
    pub frames: Vec<Frame>,
    /// Assembly, analysis and factorisation, once (s).
    pub setup_seconds: f64,
    /// Wall time of the steps (s) and steps per second.
    pub step_seconds: f64,
    pub frames_per_second: f64,
    /// Frame times (ms): the median (the sustained rate), the 95th percentile and the worst
    /// (the steps that refresh the factor while a load sets in).
    pub frame_ms: FrameTimes,
    /// Conjugate-gradient iterations, mean per step.
    pub mean_cg_iterations: f64,
    /// Preconditioner refreshes: scheduled ones plus those forced by a stale factor.
    pub factorisations: usize,
    /// Elements inverted or collapsed at the last step (0 for a sound simulation).
    pub failed_elements: usize,
}

/// Wall time of one step (ms), over the steps of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrameTimes {
    pub median: f64,
    pub p95: f64,
    pub max: f64,
}

impl FrameTimes {
    fn of(mut ms: Vec<f64>) -> Self {
        ms.sort_by(f64::total_cmp);
        let at = |q: f64| {
            let i = (q * (ms.len().max(1) - 1) as f64).round() as usize;
            ms.get(i).copied().unwrap_or(0.0)
        };
        FrameTimes {
            median: at(0.5),
            p95: at(0.95),
            max: at(1.0),
        }
    }
}

/// A backward-Euler integrator with its matrix factorised once for one time step.
pub struct Simulator<'s> {
    system: &'s MechanicalSystem,
    dt: f64,
    pattern: SparsePattern,
    values: Vec<f64>,
    diagonal: Vec<f64>,
    /// The cochlear dashpots times the time step (their term h·C of the step matrix).
    dashpots: Vec<Dashpot>,
    cholesky: SparseCholesky,
    operator: StepOperator,
    pcg: Pcg,
    state: CorotationalState,
    x: Vec<Point3<f64>>,
    v: Vec<Vector3<f64>>,
    /// The new velocity, flat (the CG solution).
    velocity: Vec<f64>,
    forces: Vec<Vector3<f64>>,
    rhs: Vec<f64>,
    cg_iterations: usize,
    refreshes: usize,
    /// The last step found its factor stale: the matrix is changing fast (a load is setting
    /// in), so the next step refreshes the factor before it solves rather than after two
    /// wasted iterations.
    refresh_next: bool,
}

impl<'s> Simulator<'s> {
    /// Assembles and factorises the step matrix of `system` for time step `dt` (s), starting
    /// at rest.
    pub fn new(system: &'s MechanicalSystem, dt: f64) -> Result<Self, MechanicsError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(MechanicsError::InvalidOption {
                what: "time step (s)",
                value: dt,
                expected: "finite and > 0",
            });
        }
        let model = &system.model;
        let rest = model.rest_positions();
        let mut state = CorotationalState::new(model);
        state
            .update(model, rest)
            .map_err(MechanicsError::solve("rest state"))?;
        let (alpha, beta) = (system.rayleigh.mass, system.rayleigh.stiffness);
        let diagonal: Vec<f64> = model
            .lumped_masses()
            .iter()
            .zip(&system.node_stiffness)
            .map(|(m, k)| (1.0 + dt * alpha) * m + dt * (dt + beta) * k)
            .collect();
        let dashpots = system
            .dashpots
            .iter()
            .map(|d| Dashpot {
                coefficient: dt * d.coefficient,
                ..*d
            })
            .collect();
        let pattern = SparsePattern::new(model);
        let cholesky =
            SparseCholesky::analyse(&pattern).map_err(MechanicsError::solve("step analysis"))?;
        let n = model.node_count();
        let mut sim = Simulator {
            system,
            dt,
            values: pattern.zero_values(),
            pattern,
            diagonal,
            dashpots,
            cholesky,
            operator: StepOperator::new(model),
            pcg: Pcg::new(3 * n),
            state,
            x: rest.to_vec(),
            v: vec![Vector3::zeros(); n],
            velocity: vec![0.0; 3 * n],
            forces: vec![Vector3::zeros(); n],
            rhs: vec![0.0; 3 * n],
            cg_iterations: 0,
            refreshes: 0,
            refresh_next: false,
        };
        sim.factorise()?;
        sim.refreshes = 1;
        Ok(sim)
    }

    /// Assembles and factorises the step matrix at the current positions (the state's
    /// rotations must be those of the current positions): the preconditioner of the next
    /// steps.
    fn factorise(&mut self) -> Result<(), MechanicsError> {
        let s = self.system;
        let scale = self.dt * (self.dt + s.rayleigh.stiffness);
        self.pattern
            .assemble(
                &s.model,
                &self.state,
                scale,
                Some(&self.diagonal),
                &s.fixed,
                &mut self.values,
            )
            .map_err(MechanicsError::solve("step matrix"))?;
        self.pattern
            .add_membrane_stress_stiffness(
                &s.model,
                &self.x,
                &self.state,
                scale,
                &s.fixed,
                &mut self.values,
            )
            .map_err(MechanicsError::solve("step matrix"))?;
        self.pattern
            .add_dashpots(&self.dashpots, &s.fixed, &mut self.values)
            .map_err(MechanicsError::solve("step matrix"))?;
        self.cholesky
            .factorise(self.pattern.matrix(&self.values))
            .map_err(MechanicsError::solve("step factorisation"))
    }

    /// Current positions (mm).
    pub fn positions(&self) -> &[Point3<f64>] {
        &self.x
    }

    /// One step under ear-canal pressure `pressure_pa` and a medial umbo force
    /// `umbo_force_un`; the preconditioner is refreshed first if `refactor`.
    pub fn step(
        &mut self,
        pressure_pa: f64,
        umbo_force_un: f64,
        refactor: bool,
    ) -> Result<(), MechanicsError> {
        let s = self.system;
        let model = &s.model;
        model
            .elastic_forces(&self.x, &mut self.state, &mut self.forces)
            .map_err(MechanicsError::solve("elastic forces"))?;
        self.operator
            .update(model, &self.x, &self.state)
            .map_err(MechanicsError::solve("step operator"))?;
        if refactor || std::mem::take(&mut self.refresh_next) {
            self.refreshes += 1;
            self.factorise()?;
        }
        for spring in &s.springs {
            let v = spring.node as usize;
            self.forces[v] += (spring.target - self.x[v]) * spring.stiffness;
        }
        PressureLoad {
            triangles: &s.eardrum,
            pressure: -pressure_pa,
        }
        .add_forces(&self.x, &mut self.forces);
        let f = s.medial * umbo_force_un;
        for (&v, &w) in s.umbo.nodes.iter().zip(&s.umbo.weights) {
            self.forces[v as usize] += f * w;
        }
        let h = self.dt;
        for (((r, f), vel), m) in self
            .rhs
            .chunks_exact_mut(3)
            .zip(&self.forces)
            .zip(&self.v)
            .zip(model.lumped_masses())
        {
            let b = vel * *m + f * h;
            r.copy_from_slice(b.as_slice());
        }
        s.fixed.zero_fixed(&mut self.rhs);
        let scale = h * (h + s.rayleigh.stiffness);
        let (operator, state, diagonal, dashpots) = (
            &mut self.operator,
            &self.state,
            &self.diagonal,
            &self.dashpots,
        );
        let apply = |p: &[f64], y: &mut [f64]| {
            operator.apply(model, state, scale, diagonal, dashpots, &s.fixed, p, y)
        };
        // CG from zero: the steps are quasi-static (the Rayleigh damping settles the ear well
        // within one 0.04 s step), so the last velocity is no better a guess, and a zero one
        // saves a product (measured: 1.2 CG iterations per step from zero, 1.3 from the last
        // velocity)
        self.velocity.fill(0.0);
        match self.pcg.solve(
            apply,
            &mut self.cholesky,
            &self.rhs,
            &mut self.velocity,
            CG_TOLERANCE,
            CG_MAX_ITERATIONS,
        ) {
            Ok(iterations) => self.cg_iterations += iterations,
            Err(crate::fem::FemError::IterativeNotConverged { iterations, .. }) => {
                // the preconditioner is too stale: refresh it and solve with it
                self.cg_iterations += iterations;
                self.refreshes += 1;
                self.refresh_next = true;
                self.factorise()?;
                self.velocity.copy_from_slice(&self.rhs);
                self.cholesky
                    .solve_in_place(&mut self.velocity)
                    .map_err(MechanicsError::solve("step solve"))?;
            }
            Err(e) => return Err(MechanicsError::solve("step solve")(e)),
        }
        if let Some(i) = self.velocity.iter().position(|r| !r.is_finite()) {
            return Err(MechanicsError::Solve {
                stage: "step".into(),
                source: crate::fem::FemError::NonFinite {
                    what: "new velocity of DOF",
                    index: i,
                },
            });
        }
        for ((p, vel), r) in self
            .x
            .iter_mut()
            .zip(self.v.iter_mut())
            .zip(self.velocity.chunks_exact(3))
        {
            *vel = Vector3::new(r[0], r[1], r[2]);
            *p += *vel * h;
        }
        Ok(())
    }

    /// The umbo now.
    fn frame(&self, time_s: f64) -> Frame {
        let s = self.system;
        let u = s.umbo.position(&self.x);
        let u0 = s.umbo.position(s.model.rest_positions());
        Frame {
            time_s,
            umbo_medial_mm: (u - u0).dot(&s.medial),
            umbo: [u.x, u.y, u.z],
        }
    }
}

/// Steps `system` from rest and records the umbo at every step.
pub fn simulate(
    system: &MechanicalSystem,
    options: &SimulationOptions,
) -> Result<Simulation, MechanicsError> {
    for (what, v) in [
        ("pressure (Pa)", options.pressure_pa),
        ("umbo force (µN)", options.umbo_force_un),
    ] {
        if !v.is_finite() {
            return Err(MechanicsError::InvalidOption {
                what,
                value: v,
                expected: "finite",
            });
        }
    }
    let t = std::time::Instant::now();
    let mut sim = Simulator::new(system, options.dt)?;
    let setup_seconds = t.elapsed().as_secs_f64();
    let mut frames = Vec::with_capacity(options.steps + 1);
    frames.push(sim.frame(0.0));
    let t = std::time::Instant::now();
    let every = options.refactor_every.max(1);
    let mut frame_ms = Vec::with_capacity(options.steps);
    for k in 1..=options.steps {
        let refactor = k > 1 && (k - 1) % every == 0;
        let frame = std::time::Instant::now();
        sim.step(options.pressure_pa, options.umbo_force_un, refactor)?;
        frame_ms.push(frame.elapsed().as_secs_f64() * 1e3);
        frames.push(sim.frame(k as f64 * options.dt));
    }
    let step_seconds = t.elapsed().as_secs_f64();
    sim.state
        .update(&system.model, &sim.x)
        .map_err(MechanicsError::solve("final state"))?;
    Ok(Simulation {
        frames,
        setup_seconds,
        step_seconds,
        frames_per_second: options.steps as f64 / step_seconds.max(1e-12),
        frame_ms: FrameTimes::of(frame_ms),
        failed_elements: sim.state.failed_elements().len(),
        mean_cg_iterations: sim.cg_iterations as f64 / options.steps.max(1) as f64,
        factorisations: sim.refreshes,
    })
}
