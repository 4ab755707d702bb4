//! The mechanics of the embedded atlas: its ossicles weigh what weighed ones do; its transfer
//! function passes the literature gates, the 250-500 Hz slope on the band's edge
//! (docs/mechanics.md, "The malleus's mass"); a
//! rigidly moved copy (a "package" differing by a rigid motion only) has identical
//! mechanics; the follower-pressure static solve at low pressure agrees with the harmonic
//! solver at zero frequency (two independent code paths: Newton + Cholesky, complex LU); the
//! real-time simulation under a constant pressure settles on the static solution; the
//! pathologies (fixations, disarticulation) move the response as temporal bones do; the
//! eardrum stiffens under static pressure as temporal bones under middle-ear pressure do; rigid
//! ossicles (the package check's model) answer within bone's own flexibility of the elastic
//! ones; a static branch that cannot carry its load stops short, says where, and fails its
//! gates.

use nalgebra::{Point3, Rotation3, Vector3};
use otoatlas::atlas::{Part, default_atlas};
use otoatlas::fem::FactorPrecision;
use otoatlas::fem::HarmonicSolver;
use otoatlas::mechanics::simulate::{SimulationOptions, simulate};
use otoatlas::mechanics::udsp::GATE_PRESSURES_PA;
use otoatlas::mechanics::{
    Condition, Drive, MechanicalSystem, Ossicles, StaticCurve, TfaOptions, TransferFunction,
    UdspOptions, condition_changes, evidence, literature_verdict, relative_verdict,
    static_pressure_curve, transfer_function,
};

/// Every transfer-function gate passes but two: the 250-500 Hz slope, which the atlas fails at
/// 9.24 dB/octave (band 3-9), as the fine atlas of the same anatomy fails it: its suspension
/// resonates near 300 Hz (docs/mechanics.md, "What the notch at 315 Hz is"); and, since the
/// cochlear load is Aibara et al.'s mean (2026-12-01), the drop from the maximum to 4 kHz,
/// 7.88 dB against 8-25 (the load flattens the maximum). Not evidence either way: the test
/// pins where the atlas stands on those gates, which the evidence judges (docs/mechanics.md,
/// "Parameters").
#[test]
fn the_atlas_transfer_function_fails_only_the_slope_and_the_drop_gates() {
    let atlas = default_atlas().unwrap();
    let system = MechanicalSystem::new(&atlas, atlas.nodes()).unwrap();
    let tf =
        transfer_function(&system, &TfaOptions::default(), &otoatlas::progress::Silent).unwrap();
    let verdict = literature_verdict(&tf, &StaticCurve::default());
    for g in &verdict.gates {
        println!(
            "{} {} = {:.3} in [{}, {}]",
            g.passed, g.name, g.value, g.low, g.high
        );
    }
    let tf_failures: Vec<_> = verdict
        .failures()
        .filter(|g| !g.name.starts_with("UDSP"))
        .map(|g| (g.name.as_str(), g.value))
        .collect();
    assert_eq!(tf_failures.len(), 2, "{tf_failures:?}");
    assert!(
        tf_failures[0].0.starts_with("slope 250-500 Hz") && (9.0..=9.5).contains(&tf_failures[0].1),
        "{tf_failures:?}"
    );
    assert!(
        tf_failures[1].0.starts_with("drop from max") && (7.5..8.0).contains(&tf_failures[1].1),
        "{tf_failures:?}"
    );
    // stiffness-controlled at 250 Hz: velocity leads the pressure (by less than a pure
    // stiffness's 90°: the cochlear load is resistive)
    let phase = tf.at(250.0).unwrap().phase_deg;
    assert!((20.0..=90.0).contains(&phase), "{phase}");
}

/// The default atlas's malleus and incus weigh what weighed ossicles do: Todd & Creighton 2013
/// (Ann Otol Rhinol Laryngol 122:60, 41 adult crania), mallei 21.2-30.7 mg, incudes
/// 24.4-37.4 mg. The malleus's density was set for this (26.0 mg, the range's middle, on the
/// anatomy's volume, whose masses every mesh of it carries); with the source study's region
/// densities it weighed 40.6 mg. The incus keeps those densities (34.4 mg).
#[test]
fn the_atlas_ossicles_weigh_what_weighed_ossicles_do() {
    let atlas = default_atlas().unwrap();
    let mass_mg = |part: Part| -> f64 {
        atlas
            .regions
            .iter()
            .filter(|r| r.part == part)
            .map(|r| {
                let rho = atlas.materials[&r.material].density_kg_m3;
                // mm³ × kg/m³ = 1e-9 kg = 1e-3 mg
                atlas.mesh.tets.region_volume(r.label) * rho * 1e-3
            })
            .sum()
    };
    let (malleus, incus) = (mass_mg(Part::Malleus), mass_mg(Part::Incus));
    println!("malleus {malleus:.2} mg, incus {incus:.2} mg");
    assert!((21.2..=30.7).contains(&malleus), "malleus {malleus} mg");
    assert!((24.4..=37.4).contains(&incus), "incus {incus} mg");
}

#[test]
fn a_rigidly_moved_atlas_has_identical_mechanics() {
    let atlas = default_atlas().unwrap();
    let rotation = Rotation3::from_euler_angles(0.4, -0.7, 1.9);
    let shift = Vector3::new(-31.0, 12.5, 140.0);
    let moved: Vec<Point3<f64>> = atlas.nodes().iter().map(|p| rotation * p + shift).collect();
    let options = TfaOptions {
        frequencies_hz: vec![500.0, 1000.0, 4000.0],
        ..TfaOptions::default()
    };
    let udsp = UdspOptions {
        pressures_pa: vec![500.0],
        ..UdspOptions::default()
    };
    let rigid = TfaOptions {
        ossicles: Ossicles::Rigid,
        ..options.clone()
    };
    let mut results = Vec::new();
    for nodes in [atlas.nodes(), &moved[..]] {
        let system = MechanicalSystem::new(&atlas, nodes).unwrap();
        let tf = transfer_function(&system, &options, &otoatlas::progress::Silent).unwrap();
        let tf_rigid = transfer_function(&system, &rigid, &otoatlas::progress::Silent).unwrap();
        let curve = static_pressure_curve(&system, &udsp, &otoatlas::progress::Silent).unwrap();
        results.push(((tf, tf_rigid), curve.at(500.0).unwrap()));
    }
    let (((tf0, r0), u0), ((tf1, r1), u1)) = (&results[0], &results[1]);
    let pairs = tf0.points.iter().zip(&tf1.points);
    for (a, b) in pairs.chain(r0.points.iter().zip(&r1.points)) {
        let rel =
            (a.magnitude_um_s_per_pa - b.magnitude_um_s_per_pa).abs() / a.magnitude_um_s_per_pa;
        assert!(rel < 1e-7, "{a:?} vs {b:?}");
        assert!((a.phase_deg - b.phase_deg).abs() < 1e-5, "{a:?} vs {b:?}");
    }
    assert!(
        *u0 > 0.0,
        "positive pressure pushes the umbo medially: {u0}"
    );
    assert!((u0 - u1).abs() < 1e-4 * u0.abs(), "{u0} vs {u1}");
}

/// The package check's model, each ossicle one rigid body, against the full model on the
/// default atlas: three bodies, and the transfer function and static curve within what bone
/// at 14 GPa bends (measured 2026-11-28: |H_V| within 0.35 dB, phase within 4.8°, umbo
/// velocity 0.26 dB, all largest at 8 kHz; umbo displacement 1.0-2.0 % smaller at the gate
/// pressures; the same atlas with bone 100 times stiffer moves as much; docs/mechanics.md,
/// "The package check with rigid ossicles"). With the cochlear load at Aibara et al.'s mean
/// (2026-12-01) the umbo velocity at 8 kHz moves by 0.43 dB, so its bound is the magnitude's.
#[test]
fn rigid_ossicles_answer_within_the_bones_own_flexibility() {
    let atlas = default_atlas().unwrap();
    let system = MechanicalSystem::new(&atlas, atlas.nodes()).unwrap();
    assert_eq!(system.ossicles.count(), 3);
    let tf = |ossicles| {
        let options = TfaOptions {
            ossicles,
            ..TfaOptions::default()
        };
        transfer_function(&system, &options, &otoatlas::progress::Silent).unwrap()
    };
    let (elastic, rigid) = (tf(Ossicles::Elastic), tf(Ossicles::Rigid));
    assert_eq!(rigid.ossicles, Ossicles::Rigid);
    for (a, b) in elastic.points.iter().zip(&rigid.points) {
        let db = b.db() - a.db();
        let umbo = 20.0 * (b.umbo_um_s_per_pa / a.umbo_um_s_per_pa).log10();
        let phase = b.phase_deg - a.phase_deg;
        println!(
            "{:6.0} Hz: {db:+.3} dB {phase:+.2} deg, umbo {umbo:+.3} dB",
            a.frequency_hz
        );
        assert!(
            db.abs() < 0.5 && phase.abs() < 6.0 && umbo.abs() < 0.5,
            "{a:?} vs {b:?}"
        );
    }
    let curve = |ossicles| {
        let options = UdspOptions {
            pressures_pa: GATE_PRESSURES_PA.to_vec(),
            tolerance_mm: 1e-4,
            ossicles,
            ..UdspOptions::default()
        };
        static_pressure_curve(&system, &options, &otoatlas::progress::Silent).unwrap()
    };
    let (elastic, rigid) = (curve(Ossicles::Elastic), curve(Ossicles::Rigid));
    assert_eq!(rigid.ossicles, Ossicles::Rigid);
    assert!(rigid.failure.is_none(), "{rigid:?}");
    for p in GATE_PRESSURES_PA {
        let ratio = rigid.at(p).unwrap() / elastic.at(p).unwrap();
        println!("{p:6.0} Pa: rigid / elastic umbo displacement {ratio:.4}");
        assert!((0.97..1.0).contains(&ratio), "{p} Pa: {ratio}");
    }
}

/// A curve whose increments cannot reach equilibrium (one Newton iteration each, no halving
/// allowed) keeps only its rest point and says where each branch stopped; against the atlas's
/// own curve (the shipped reference) every static gate fails, the loaded-to-the-end one
/// included, and the transfer function's pass. A
/// registered model that cannot carry the load is a finding of the check, not an error.
#[test]
fn a_static_branch_that_cannot_carry_its_load_stops_short_and_fails_its_gates() {
    let atlas = default_atlas().unwrap();
    let system = MechanicalSystem::new(&atlas, atlas.nodes()).unwrap();
    let options = UdspOptions {
        pressures_pa: GATE_PRESSURES_PA.to_vec(),
        max_iterations: 1,
        min_step_pa: 2000.0,
        ossicles: Ossicles::Rigid,
        tangent_precision: FactorPrecision::Single,
        ..UdspOptions::default()
    };
    let curve = static_pressure_curve(&system, &options, &otoatlas::progress::Silent).unwrap();
    println!("{curve:?}");
    assert_eq!(curve.points.len(), 1);
    assert_eq!(curve.at(0.0), Some(0.0));
    let failure = curve.failure.as_deref().unwrap();
    assert!(
        failure.contains("static pressure -1000 Pa") && failure.contains("static pressure 1000 Pa"),
        "{failure}"
    );
    let reference = otoatlas::pipeline::mechanics::embedded_reference().unwrap();
    // the atlas's own transfer function on both sides: only the static gates can fail
    let tf = &reference.transfer_function;
    let verdict = relative_verdict(tf, &curve, tf, &reference.static_pressure);
    let (transfer_gates, static_gates): (Vec<_>, Vec<_>) = verdict
        .gates
        .iter()
        .partition(|g| g.name.contains("Hz") || g.name.contains("maximum"));
    // six pressures, the asymmetry, its side, the load carried to the end
    assert_eq!(
        static_gates.len(),
        GATE_PRESSURES_PA.len() + 3,
        "{static_gates:?}"
    );
    assert!(static_gates.iter().all(|g| !g.passed), "{static_gates:?}");
    assert!(
        transfer_gates.iter().all(|g| g.passed),
        "{transfer_gates:?}"
    );
    assert!(!verdict.passed);
}

/// An increment that a single-precision tangent cannot bring to equilibrium within the
/// iteration limit is solved again in double precision (`UdspOptions::tangent_precision`),
/// and the curve says from where: the limit is set one below what the single-precision
/// tangent needs at ±1 kPa on the atlas (measured first, so that the test reaches the retry on
/// any machine), and the curve so solved is the double-precision one.
#[test]
fn an_increment_single_precision_cannot_solve_is_solved_in_double() {
    let atlas = default_atlas().unwrap();
    let system = MechanicalSystem::new(&atlas, atlas.nodes()).unwrap();
    let curve = |precision, max_iterations| {
        let options = UdspOptions {
            pressures_pa: vec![-1000.0, 1000.0],
            tolerance_mm: 1e-7,
            residual_tolerance: 1e-6,
            max_iterations,
            ossicles: Ossicles::Rigid,
            tangent_precision: precision,
            ..UdspOptions::default()
        };
        static_pressure_curve(&system, &options, &otoatlas::progress::Silent).unwrap()
    };
    let double = curve(FactorPrecision::Double, 200);
    let single = curve(FactorPrecision::Single, 200);
    assert!(double.failure.is_none() && single.failure.is_none());
    assert!(single.double_precision_from_pa.is_empty());
    let needed = single
        .points
        .iter()
        .map(|p| p.iterations)
        .filter(|&n| n > 0);
    let limit = needed.min().unwrap() - 1;
    let retried = curve(FactorPrecision::Single, limit);
    println!(
        "single precision needs {:?} iterations; at most {limit}: went on in double from {:?} Pa",
        single
            .points
            .iter()
            .map(|p| p.iterations)
            .collect::<Vec<_>>(),
        retried.double_precision_from_pa
    );
    assert!(retried.failure.is_none(), "{:?}", retried.failure);
    assert_eq!(retried.double_precision_from_pa, [-1000.0, 1000.0]);
    for p in [-1000.0, 1000.0] {
        let (got, want) = (retried.at(p).unwrap(), double.at(p).unwrap());
        assert!(
            (got - want).abs() < 1e-6,
            "{p} Pa: {got} mm, double {want} mm"
        );
    }
}

/// The umbo's static displacement (mm, medial) at pressure `p`, solved to `tolerance_mm`.
fn static_umbo(system: &MechanicalSystem, p: f64, tolerance_mm: f64) -> f64 {
    let curve = static_pressure_curve(
        system,
        &UdspOptions {
            pressures_pa: vec![p],
            tolerance_mm,
            ..UdspOptions::default()
        },
        &otoatlas::progress::Silent,
    )
    .unwrap();
    curve.at(p).unwrap()
}

#[test]
fn low_static_pressure_matches_the_zero_frequency_harmonic_solution() {
    let atlas = default_atlas().unwrap();
    let system = MechanicalSystem::new(&atlas, atlas.nodes()).unwrap();
    let p = 2.0;
    let nonlinear = static_umbo(&system, p, 1e-9);
    let harmonic = HarmonicSolver::new(
        &system.model,
        &system.fixed,
        &system.node_stiffness,
        &system.dashpots,
        system.rayleigh,
    )
    .unwrap();
    let x = system.model.rest_positions();
    let mut f = vec![Vector3::zeros(); x.len()];
    otoatlas::fem::PressureLoad {
        triangles: &system.eardrum,
        pressure: -p,
    }
    .add_forces(x, &mut f);
    let u = harmonic.solve(0.0, &f).unwrap();
    let linear: f64 = system
        .umbo
        .nodes
        .iter()
        .zip(&system.umbo.weights)
        .map(|(&v, &w)| {
            let d = u[v as usize];
            w * (d[0].re * system.medial.x + d[1].re * system.medial.y + d[2].re * system.medial.z)
        })
        .sum();
    println!("umbo at {p} Pa: follower Newton {nonlinear:e} mm, linear {linear:e} mm");
    assert!(
        (nonlinear - linear).abs() < 0.01 * linear.abs(),
        "{nonlinear} vs {linear}"
    );
}

/// Lowering the middle ear's pressure stiffens the eardrum: Gyo & Goode 1987 (Auris Nasus
/// Larynx 14:131, 5 temporal bones) measured the umbo's vibration below 2 kHz fall by
/// 5.0 ± 1.0, 9.2 ± 1.3 and 13.1 ± 1.8 dB at 100, 200 and 300 mmH2O below the canal's
/// pressure. The model's low-frequency limit is its static compliance du/dp there against at
/// rest (docs/mechanics.md, "Evidence"); the curve's five-point slope is checked against
/// equilibria solved 25 Pa either side. Murakami et al. 1997 (Acta Otolaryngol 117:390,
/// 15 bones): pressure either way lowers the low-frequency vibration, the middle ear's
/// negative pressure (p > 0 here) more than its positive. Nothing was fitted to either; the
/// eardrum's bow, fitted to the same curve's asymmetry, shapes it.
#[test]
fn static_pressure_stiffens_the_ear_as_temporal_bones_under_middle_ear_pressure_do() {
    let atlas = default_atlas().unwrap();
    let system = MechanicalSystem::new(&atlas, atlas.nodes()).unwrap();
    let curve = static_pressure_curve(
        &system,
        &UdspOptions::default(),
        &otoatlas::progress::Silent,
    )
    .unwrap();
    let mm_h2o = 9.80665;
    let exact = |p: f64| {
        let solve = |q: f64| static_umbo(&system, q, 1e-8);
        (solve(p + 25.0) - solve(p - 25.0)) / 50.0
    };
    let at_rest = curve.compliance_at(0.0).unwrap();
    let first = 100.0 * mm_h2o;
    for (p, c) in [(0.0, at_rest), (first, curve.compliance_at(first).unwrap())] {
        let e = exact(p);
        assert!((c / e - 1.0).abs() < 2e-3, "{p} Pa: {c} against {e}");
    }
    // the static sources only: no transfer function
    let tf = TransferFunction {
        drive: Drive::Eardrum,
        drive_pa: 1.0,
        ossicles: Ossicles::Elastic,
        points: Vec::new(),
    };
    let gyo = evidence(&tf, &curve, 3.3)
        .into_iter()
        .find(|e| e.source.starts_with("Gyo & Goode 1987"))
        .unwrap();
    for point in &gyo.points {
        println!("{point:?}");
    }
    assert_eq!(gyo.points.len(), 3);
    assert!(gyo.within_spread, "{gyo:?}");
    for mm in [100.0, 200.0, 300.0] {
        let p = mm * mm_h2o;
        let loss = |q: f64| 20.0 * (curve.compliance_at(q).unwrap() / at_rest).log10();
        assert!(
            loss(p) < loss(-p) && loss(-p) < 0.0,
            "{mm} mmH2O: {} dB, the opposite pressure {} dB",
            loss(p),
            loss(-p)
        );
    }
}

/// Backward Euler (one linearised solve per step, matrix-free CG with a stale Cholesky
/// preconditioner) under a constant 1 kPa comes to rest on the static equilibrium of the
/// incremental Newton solve: a step's fixed point is a zero out-of-balance force whatever the
/// solver's tolerance, so this checks the simulation's forces and its convergence.
#[test]
fn simulation_under_constant_pressure_settles_on_the_static_solution() {
    let atlas = default_atlas().unwrap();
    let system = MechanicalSystem::new(&atlas, atlas.nodes()).unwrap();
    let p = 1000.0;
    let sim = simulate(
        &system,
        &SimulationOptions {
            steps: 200,
            pressure_pa: p,
            ..SimulationOptions::default()
        },
    )
    .unwrap();
    let stat = static_umbo(&system, p, 1e-8);
    let last = sim.frames.last().unwrap().umbo_medial_mm;
    let before = sim.frames[sim.frames.len() - 11].umbo_medial_mm;
    println!(
        "umbo at {p} Pa: simulated {last:e} mm (10 steps before {before:e}), static {stat:e} mm; \
         {:.2} CG iterations/step, {} factorisations",
        sim.mean_cg_iterations, sim.factorisations
    );
    assert_eq!(sim.failed_elements, 0);
    assert!((last - stat).abs() < 1e-5 * stat, "{last} vs {stat}");
    assert!((last - before).abs() < 1e-5 * stat, "{last} vs {before}");
}

/// Each pathology moves the stapes and umbo velocities as temporal bones do (the changes and
/// ranges of `condition_changes`: Nakajima et al. 2005; Huber et al. 2003; docs/mechanics.md,
/// "Pathologies") and fails a normal-ear transfer-function gate (7 frequencies each, enough
/// for the maximum: this test is cheap).
#[test]
fn pathologies_move_the_response_as_measured_and_fail_the_normal_bands() {
    let atlas = default_atlas().unwrap();
    let tf_of = |condition: Condition, frequencies_hz: Vec<f64>| {
        let ear = condition.apply(&atlas).unwrap();
        let system = MechanicalSystem::new(&ear, ear.nodes()).unwrap();
        let options = TfaOptions {
            frequencies_hz,
            ..TfaOptions::default()
        };
        transfer_function(&system, &options, &otoatlas::progress::Silent).unwrap()
    };
    let normal = tf_of(
        Condition::Normal,
        vec![250.0, 500.0, 1000.0, 2000.0, 4000.0],
    );
    for (condition, checks, gate) in [
        (Condition::StapesFixation, 8, "|H_V| at 250 Hz"),
        (Condition::MalleusFixation, 6, "frequency of max"),
        (Condition::IsDisarticulation, 8, "|H_V| at 250 Hz"),
    ] {
        let ear = tf_of(
            condition,
            vec![250.0, 500.0, 1000.0, 1587.0, 2000.0, 2520.0, 4000.0],
        );
        let changes = condition_changes(condition, &normal, &ear);
        for c in &changes {
            println!(
                "{condition:?}: {:?} {} Hz {:+.1} dB in [{:?}, {:?}]",
                c.velocity, c.frequency_hz, c.model_db, c.low_db, c.high_db
            );
        }
        assert_eq!(changes.len(), checks, "{changes:?}");
        assert!(changes.iter().all(|c| c.within), "{condition:?}");
        // the normal-ear gate it must fail
        let verdict = literature_verdict(&ear, &StaticCurve::default());
        let failed: Vec<(&str, f64)> = verdict
            .failures()
            .map(|g| (g.name.as_str(), g.value))
            .collect();
        println!("  fails {failed:?}");
        assert!(
            failed.iter().any(|(name, _)| name.starts_with(gate)),
            "{condition:?} passes the normal ear's gate {gate}"
        );
    }
}

/// The eardrum's mesh is converged (issue: ≤ 1 dB and ≤ 5 % under drum refinement), by the
/// study `validate --convergence` runs: the default atlas rebuilt from its anatomy with
/// drum triangles √2 and 2 times smaller (about 2 and 4 times as many), each tied to the
/// manubrium along its attachment line: both coarser drums within the bounds of the finest
/// (2026-11-27: 0.13 and 0.10 dB, 0.19 and 0.64 % at ±1 and ±4 kPa; below 1 % the static
/// differences are not ordered by refinement). Before the tie (2026-11-27) the
/// refined drum was 1.1-3.8 dB lower above 2 kHz and 22-27 % stiffer under over-pressure
/// (docs/mechanics.md, "The eardrum's own convergence").
#[test]
#[ignore = "heavy: builds two atlases with finer drums and runs both checks on each"]
fn refining_the_eardrum_moves_its_mechanics_by_under_1_db_and_5_percent() {
    use otoatlas::atlas::Anatomy;
    use otoatlas::mechanics::{DrumStudy, ValidationOptions, mechanics};
    let atlas = default_atlas().unwrap();
    let anatomy = Anatomy::default_right().unwrap();
    let options = ValidationOptions {
        udsp: Some(UdspOptions {
            pressures_pa: vec![-4000.0, -1000.0, 1000.0, 4000.0],
            ..UdspOptions::default()
        }),
        ..ValidationOptions::default()
    };
    let silent = &otoatlas::progress::Silent;
    let own = mechanics(&atlas, atlas.nodes(), &options, silent).unwrap();
    let study = DrumStudy::new(&atlas, &anatomy)
        .unwrap()
        .run(&own, &options, silent)
        .unwrap();
    let levels = &study.levels;
    for l in levels {
        println!(
            "{:.3} mm, {} triangles: {:.3} dB, {:.2} %, {}",
            l.membrane_edge_mm,
            l.membrane_triangles,
            l.worst_db,
            100.0 * l.worst_static_fraction,
            l.manubrium_attachment
        );
    }
    assert_eq!(levels.len(), 3);
    assert_eq!(levels[0].membrane_triangles, atlas.mesh.triangles.len());
    assert!(levels[1].membrane_triangles > 18 * levels[0].membrane_triangles / 10);
    assert!(levels[2].membrane_triangles > 3 * levels[0].membrane_triangles);
    assert!(study.converged, "{study:?}");
    for l in &levels[..2] {
        assert!(
            l.worst_db <= 1.0 && l.worst_static_fraction <= 0.05,
            "{l:?}"
        );
    }
    assert_eq!(levels[2].worst_db, 0.0);
    assert_eq!(levels[2].worst_static_fraction, 0.0);
}
