//! The filter on a small simulated room: tracking, global localization, determinism, and
//! bad input.

use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;
use slam_mcl::{InitialBelief, Mcl, MclConfig, MclMap, SensorKind};
use slam_models::{Pose2, ScanRecord};
use slam_sim::laser::{LaserScanner, Segment, World};

/// An L-shaped room (no symmetry) with a box.
fn room() -> World {
    let p = |x: f64, y: f64| slam_models::Point2::new(x, y);
    let mut w = vec![
        p(0.0, 0.0),
        p(8.0, 0.0),
        p(8.0, 4.0),
        p(4.0, 4.0),
        p(4.0, 7.0),
        p(0.0, 7.0),
    ];
    w.push(w[0]);
    let mut s: Vec<Segment> = w
        .windows(2)
        .map(|a| Segment::new(a[0].x, a[0].y, a[1].x, a[1].y))
        .collect();
    s.push(Segment::new(5.5, 1.0, 6.5, 1.0));
    s.push(Segment::new(6.5, 1.0, 6.5, 1.8));
    s.push(Segment::new(6.5, 1.8, 5.5, 1.8));
    s.push(Segment::new(5.5, 1.8, 5.5, 1.0));
    World::new(s).unwrap()
}

/// Drives from (1.5, 1.5) east then north (true poses), odometry = truth; returns the
/// final error, the final spread and the whole output for determinism checks.
fn run(config: MclConfig, init: InitialBelief, seed: u64) -> (f64, f64, Vec<Pose2>) {
    let world = room();
    let map = MclMap::new(world.rasterize(0.05, 0.5).unwrap(), &config).unwrap();
    let mut mcl = Mcl::new(config, map, init, seed).unwrap();
    let scanner = LaserScanner::default();
    let mut rng = Pcg64Mcg::seed_from_u64(1);
    let mut poses = Vec::new();
    let mut last = (0.0, 0.0);
    for k in 0..60 {
        let truth = if k < 30 {
            Pose2::new(1.5 + 0.15 * k as f64, 1.5, 0.0)
        } else {
            Pose2::new(5.85 - 0.1 * (k - 30) as f64, 2.5, std::f64::consts::PI)
        };
        let scan = scanner.scan(&world, &truth, &mut rng);
        let info = mcl
            .process(&ScanRecord {
                t: k as f64,
                odometry: truth,
                scan: Some(scan),
            })
            .unwrap();
        poses.push(info.pose);
        last = (info.pose.distance(&truth), info.spread);
    }
    (last.0, last.1, poses)
}

#[test]
fn tracks_from_a_known_start_with_both_models() {
    for model in [SensorKind::LikelihoodField, SensorKind::Beam] {
        let mut c = MclConfig::default();
        c.sensor.model = model;
        c.kld.max_particles = 1000;
        let init = InitialBelief::Gaussian {
            mean: Pose2::new(1.6, 1.4, 0.05),
            sigma: [0.2, 0.2, 0.1],
        };
        let (err, spread, _) = run(c, init, 2);
        assert!(
            err < 0.1 && spread < 0.3,
            "{model:?}: error {err} m, spread {spread} m"
        );
    }
}

#[test]
fn finds_itself_from_nowhere_and_repeats_its_bytes() {
    let (err, spread, a) = run(MclConfig::default(), InitialBelief::Global, 4);
    assert!(
        err < 0.1 && spread < 0.3,
        "error {err} m, spread {spread} m"
    );
    let (_, _, b) = run(MclConfig::default(), InitialBelief::Global, 4);
    assert_eq!(a, b, "same seed, different output");
    let (_, _, c) = run(MclConfig::default(), InitialBelief::Global, 5);
    assert_ne!(a, c);
}

#[test]
fn bad_input_is_an_error() {
    let config = MclConfig::default();
    let map = MclMap::new(room().rasterize(0.05, 0.5).unwrap(), &config).unwrap();
    let nan = InitialBelief::Gaussian {
        mean: Pose2::new(f64::NAN, 0.0, 0.0),
        sigma: [0.1; 3],
    };
    assert!(Mcl::new(config, map.clone(), nan, 0).is_err());
    let mut mcl = Mcl::new(config, map, InitialBelief::Global, 0).unwrap();
    let rec = ScanRecord {
        t: 0.0,
        odometry: Pose2::new(0.0, f64::INFINITY, 0.0),
        scan: None,
    };
    assert!(mcl.process(&rec).is_err());
    // A map without free space.
    let full = slam_models::GridMap {
        cells: vec![100; 4],
        ..slam_models::GridMap::unknown(0.1, slam_models::Point2::origin(), 2, 2)
    };
    assert!(matches!(
        MclMap::new(full, &config),
        Err(slam_mcl::MclError::NoFreeSpace { .. })
    ));
}

/// The global start's evidence rule (`evidence-distance`): while converging, an update's
/// exponent is k₀ · min(1, d / d_ref), d the translation since the previous update, so a
/// robot turning in place (d = 0) adds no scan evidence after the first scan; the first
/// scan and a Gaussian start use k₀ (adaptive tempering may only lower it). Expected values
/// from the rule's definition: 0 for a pure turn, at most k₀ · 0.1 / 0.2 after 0.1 m.
#[test]
fn scans_from_one_place_count_once_while_a_global_start_converges() {
    let world = room();
    let config = MclConfig {
        kld: slam_mcl::KldConfig {
            max_particles: 2000,
            ..Default::default()
        },
        ..MclConfig::default()
    };
    let k0 = config.sensor.weight_exponent;
    let scanner = LaserScanner::default();
    let mut rng = Pcg64Mcg::seed_from_u64(1);
    let mut exponents = |init: InitialBelief| -> Vec<(f64, bool)> {
        let map = MclMap::new(world.rasterize(0.05, 0.5).unwrap(), &config).unwrap();
        let mut mcl = Mcl::new(config, map, init, 3).unwrap();
        // Turn in place by 0.3 rad four times, then drive 0.1 m while turning 0.3 rad.
        let mut truths: Vec<Pose2> = (0..5)
            .map(|k| Pose2::new(2.0, 2.0, 0.3 * k as f64))
            .collect();
        truths.push(Pose2::new(2.1, 2.0, 1.5));
        truths
            .iter()
            .enumerate()
            .map(|(k, truth)| {
                let info = mcl
                    .process(&ScanRecord {
                        t: k as f64,
                        odometry: *truth,
                        scan: Some(scanner.scan(&world, truth, &mut rng)),
                    })
                    .unwrap();
                assert!(info.updated, "record {k} made no update");
                (info.exponent, info.converging)
            })
            .collect()
    };
    let global = exponents(InitialBelief::Global);
    assert!(global.iter().all(|(_, c)| *c), "{global:?}");
    assert!(global[0].0 > 0.0 && global[0].0 <= k0);
    for (k, c) in &global[1..5] {
        assert!(*c && *k == 0.0, "a turn in place weighed with {k}");
    }
    assert!(global[5].0 > 0.0 && global[5].0 <= k0 * 0.1 / 0.2 + 1e-12);
    let tracked = exponents(InitialBelief::Gaussian {
        mean: Pose2::new(2.0, 2.0, 0.0),
        sigma: [0.1, 0.1, 0.05],
    });
    assert!(tracked.iter().all(|(k, c)| !c && *k > 0.0), "{tracked:?}");
}

/// `max_particles` bounds the particle count at every step, the modes' top-up included:
/// from a global start (the count starts at the bound) with mode top-ups large enough to
/// pass it (8 modes × 400 particles against a bound of 1,000), no step reports more.
#[test]
fn the_particle_count_never_passes_max_particles() {
    let world = room();
    let mut config = MclConfig::default();
    config.kld.max_particles = 1000;
    config.kld.min_particles = 100;
    config.kld.mode_particles = 400;
    config.kld.mode_min_mass = 0.001;
    let map = MclMap::new(world.rasterize(0.05, 0.5).unwrap(), &config).unwrap();
    let mut mcl = Mcl::new(config, map, InitialBelief::Global, 3).unwrap();
    let scanner = LaserScanner::default();
    let mut rng = Pcg64Mcg::seed_from_u64(1);
    let mut resampled = 0;
    for k in 0..40 {
        let truth = Pose2::new(1.5 + 0.15 * k as f64, 1.5, 0.0);
        let scan = scanner.scan(&world, &truth, &mut rng);
        let info = mcl
            .process(&ScanRecord {
                t: k as f64,
                odometry: truth,
                scan: Some(scan),
            })
            .unwrap();
        resampled += usize::from(info.resampled);
        assert!(
            info.particles <= 1000,
            "step {k}: {} particles",
            info.particles
        );
        assert_eq!(info.particles, mcl.particle_count());
    }
    assert!(resampled > 0, "the check must see resamplings");
}
