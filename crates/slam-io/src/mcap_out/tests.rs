//! The run writer's file read back: by the `mcap` crate's reader, every message decoded by
//! decoders written here on the bag reader's CDR cursor (which the writer does not use),
//! and the encoder's bytes compared with those of an independent writer (the `rosbags`
//! fixtures of the bag reader).

use super::*;
use crate::rosbag::cdr::Cdr;
use crate::rosbag::wire::{DecodeError, Wire};
use slam_models::{LandmarkId, Matrix2};
use std::f64::consts::{FRAC_PI_2, PI};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("slam-mcap-out-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

// ---- decoders of the messages the writer emits (test only) ----

fn d_stamp(c: &mut Cdr<'_>) -> Result<Stamp, DecodeError> {
    let sec = c.i32("sec")?;
    let nanosec = c.u32("nanosec")?;
    assert!(nanosec < 1_000_000_000);
    Ok(Stamp { sec, nanosec })
}

fn d_header(c: &mut Cdr<'_>) -> Result<(Stamp, String), DecodeError> {
    Ok((d_stamp(c)?, c.string("frame_id")?))
}

/// A pose that must lie in the plane: z = 0 and a rotation about z only.
fn d_pose(c: &mut Cdr<'_>) -> Result<Pose2, DecodeError> {
    let (x, y, z) = (c.f64("x")?, c.f64("y")?, c.f64("z")?);
    let (qx, qy, qz, qw) = (c.f64("qx")?, c.f64("qy")?, c.f64("qz")?, c.f64("qw")?);
    assert_eq!((z, qx, qy), (0.0, 0.0, 0.0));
    assert!((qz * qz + qw * qw - 1.0).abs() < 1e-12);
    Ok(Pose2::new(x, y, 2.0 * qz.atan2(qw)))
}

fn done<T>(c: &Cdr<'_>, v: T) -> T {
    assert_eq!(c.remaining(), 0, "bytes left after the message");
    v
}

fn d_pose_stamped(b: &[u8]) -> (Stamp, String, Pose2) {
    let mut c = Cdr::new(b).unwrap();
    let (s, f) = d_header(&mut c).unwrap();
    let p = d_pose(&mut c).unwrap();
    done(&c, (s, f, p))
}

fn d_path(b: &[u8]) -> (Stamp, String, Vec<(Stamp, Pose2)>) {
    let mut c = Cdr::new(b).unwrap();
    let (s, f) = d_header(&mut c).unwrap();
    let n = c.count("poses", 8).unwrap();
    let mut v = Vec::new();
    for _ in 0..n {
        let (t, frame) = d_header(&mut c).unwrap();
        assert_eq!(frame, f);
        v.push((t, d_pose(&mut c).unwrap()));
    }
    done(&c, (s, f, v))
}

fn d_pose_array(b: &[u8]) -> Vec<Pose2> {
    let mut c = Cdr::new(b).unwrap();
    let (_, f) = d_header(&mut c).unwrap();
    assert_eq!(f, MAP_FRAME);
    let n = c.count("poses", 56).unwrap();
    let v = (0..n).map(|_| d_pose(&mut c).unwrap()).collect();
    done(&c, v)
}

struct Grid {
    frame: String,
    load_time: Stamp,
    stamp: Stamp,
    resolution: f64,
    width: u32,
    height: u32,
    origin: Pose2,
    data: Vec<i8>,
}

fn d_grid(b: &[u8]) -> Grid {
    let mut c = Cdr::new(b).unwrap();
    let (stamp, frame) = d_header(&mut c).unwrap();
    let load_time = d_stamp(&mut c).unwrap();
    let resolution = c.f32("resolution").unwrap();
    let width = c.u32("width").unwrap();
    let height = c.u32("height").unwrap();
    let origin = d_pose(&mut c).unwrap();
    let n = c.count("data", 1).unwrap();
    let data = (0..n).map(|_| c.u8("data").unwrap() as i8).collect();
    done(
        &c,
        Grid {
            frame,
            load_time,
            stamp,
            resolution,
            width,
            height,
            origin,
            data,
        },
    )
}

#[derive(Debug)]
struct DMarker {
    ns: String,
    id: i32,
    kind: i32,
    action: i32,
    pose: Pose2,
    scale: [f64; 3],
    points: Vec<(f64, f64)>,
}

fn d_markers(b: &[u8]) -> Vec<DMarker> {
    let mut c = Cdr::new(b).unwrap();
    let n = c.count("markers", 8).unwrap();
    let mut v = Vec::new();
    for _ in 0..n {
        let (_, frame) = d_header(&mut c).unwrap();
        assert_eq!(frame, MAP_FRAME);
        let ns = c.string("ns").unwrap();
        let id = c.i32("id").unwrap();
        let kind = c.i32("type").unwrap();
        let action = c.i32("action").unwrap();
        let pose = d_pose(&mut c).unwrap();
        let scale = [
            c.f64("sx").unwrap(),
            c.f64("sy").unwrap(),
            c.f64("sz").unwrap(),
        ];
        for _ in 0..4 {
            let a = c.f32("rgba").unwrap();
            assert!((0.0..=1.0).contains(&a));
        }
        assert_eq!((c.i32("lifetime").unwrap(), c.u32("ns").unwrap()), (0, 0));
        assert_eq!(c.u8("frame_locked").unwrap(), 0);
        let np = c.count("points", 24).unwrap();
        let points = (0..np)
            .map(|_| {
                let p = (c.f64("x").unwrap(), c.f64("y").unwrap());
                assert_eq!(c.f64("z").unwrap(), 0.0);
                p
            })
            .collect();
        assert_eq!(c.count("colors", 16).unwrap(), 0);
        assert_eq!(c.string("texture_resource").unwrap(), "");
        d_header(&mut c).unwrap();
        assert_eq!(c.string("format").unwrap(), "");
        assert_eq!(c.count("texture data", 1).unwrap(), 0);
        assert_eq!(c.count("uv", 8).unwrap(), 0);
        assert_eq!(c.string("text").unwrap(), "");
        assert_eq!(c.string("mesh_resource").unwrap(), "");
        assert_eq!(c.string("mesh_file.filename").unwrap(), "");
        assert_eq!(c.count("mesh_file.data", 1).unwrap(), 0);
        assert_eq!(c.u8("mesh_use_embedded_materials").unwrap(), 0);
        v.push(DMarker {
            ns,
            id,
            kind,
            action,
            pose,
            scale,
            points,
        });
    }
    done(&c, v)
}

// ---- a small run ----

const MAX_RANGE: f64 = 50.0;

fn scan(k: usize) -> LaserScan {
    LaserScan {
        angle_min: -FRAC_PI_2,
        angle_increment: PI / 180.0,
        ranges: (0..181)
            .map(|i| {
                if i % 10 == k % 10 {
                    MAX_RANGE
                } else {
                    1.0 + 0.013 * i as f64
                }
            })
            .collect(),
        max_range: MAX_RANGE,
        sensor_pose: Pose2::new(0.12, -0.03, 0.05),
    }
}

fn grid(k: usize) -> GridMap {
    let mut m = GridMap::unknown(0.05, Point2::new(-3.2, -1.55), 40, 30);
    for (i, c) in m.cells.iter_mut().enumerate() {
        *c = [(-1), 0, 100, 57][(i + k) % 4];
    }
    m
}

/// A covariance with semi-axes σ₁, σ₂ (standard deviations) along angle φ.
fn cov(s1: f64, s2: f64, phi: f64) -> Matrix2 {
    let r = Matrix2::new(phi.cos(), -phi.sin(), phi.sin(), phi.cos());
    r * Matrix2::new(s1 * s1, 0.0, 0.0, s2 * s2) * r.transpose()
}

fn landmarks(k: usize) -> Vec<LandmarkEstimate> {
    (0..3 + k % 2)
        .map(|i| LandmarkEstimate {
            id: LandmarkId(10 + i as u32),
            mean: Point2::new(2.0 * i as f64, 1.0 - i as f64),
            covariance: cov(0.3 + 0.1 * i as f64, 0.1, 0.4 * i as f64 - 0.3),
        })
        .collect()
}

const STEPS: usize = 25;

fn t_of(k: usize) -> f64 {
    976_052_890.244_09 + 0.1 * k as f64
}

fn pose_of(k: usize) -> Pose2 {
    Pose2::new(0.1 * k as f64, 0.02 * k as f64, 0.03 * k as f64 - 0.2)
}

fn odom_of(k: usize) -> Pose2 {
    Pose2::new(
        0.11 * k as f64 + 1.0,
        -0.01 * k as f64,
        0.031 * k as f64 + 2.5,
    )
}

fn particles_of(k: usize) -> Vec<WeightedPose> {
    (0..5)
        .map(|i| WeightedPose {
            pose: Pose2::new(0.1 * k as f64 + 0.01 * i as f64, 0.0, 0.1 * i as f64),
            weight: 0.2,
        })
        .collect()
}

fn trajectory() -> Vec<TimedPose> {
    (0..STEPS)
        .map(|k| TimedPose {
            t: t_of(k),
            pose: Pose2::new(pose_of(k).x + 0.5, pose_of(k).y, pose_of(k).theta),
        })
        .collect()
}

/// Writes the small run to `path`; scans at every step but each fifth.
fn write_run(path: &Path) -> TopicCounts {
    let mut w = McapRunWriter::create(
        path,
        McapRunOptions {
            snapshot_every: 10,
            true_landmarks: vec![Point2::new(0.0, 1.0), Point2::new(2.1, 0.0)],
        },
    )
    .unwrap();
    for k in 0..STEPS {
        let snap = w.snapshot_due();
        let (s, m, l, p) = (scan(k), grid(k), landmarks(k), particles_of(k));
        w.step(&RunStep {
            t: t_of(k),
            pose: pose_of(k),
            odometry: Some(odom_of(k)),
            scan: (k % 5 != 4).then_some(&s),
            particles: Some(&p),
            map: snap.then_some(&m),
            landmarks: snap.then_some(&l),
        })
        .unwrap();
    }
    let (traj, m, l) = (trajectory(), grid(99), landmarks(99));
    w.finish(&RunEnd {
        trajectory: &traj,
        map: Some(&m),
        landmarks: Some(&l),
        ground_truth: Some(&traj[..7]),
    })
    .unwrap()
}

/// The MCAP header record's profile (opcode 0x01 right after the 8-byte magic).
fn profile(buf: &[u8]) -> String {
    assert_eq!(buf[8], 0x01);
    let n = u32::from_le_bytes(buf[17..21].try_into().unwrap()) as usize;
    String::from_utf8(buf[21..21 + n].to_vec()).unwrap()
}

#[test]
fn every_message_reads_back_with_its_values() {
    let dir = scratch("all");
    let path = dir.join("run.mcap");
    let counts = write_run(&path);
    assert!(!dir.join("run.mcap.partial").exists());
    let buf = std::fs::read(&path).unwrap();
    assert_eq!(profile(&buf), "ros2");
    let summary = mcap::Summary::read(&buf).unwrap().unwrap();
    assert!(!summary.chunk_indexes.is_empty());
    for c in &summary.chunk_indexes {
        assert_eq!(c.compression, "zstd");
    }

    let mut seen: BTreeMap<String, Vec<(u64, Vec<u8>)>> = BTreeMap::new();
    for m in mcap::MessageStream::new(&buf).unwrap() {
        let m = m.unwrap();
        let ch = &m.channel;
        assert_eq!(ch.message_encoding, "cdr");
        let schema = ch.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "ros2msg");
        assert_eq!(
            *schema.data,
            *msgs::schema(&schema.name).unwrap().as_bytes(),
            "{}",
            ch.topic
        );
        assert!(ch.metadata["offered_qos_profiles"].contains("reliability: 1"));
        assert_eq!(m.log_time, m.publish_time);
        seen.entry(ch.topic.clone())
            .or_default()
            .push((m.log_time, m.data.to_vec()));
    }
    let n = |t: &str| seen.get(t).map_or(0, Vec::len);
    // Counted from the run above: snapshots after steps 10 and 20, then the end.
    let expect = [
        ("/pose", STEPS),
        ("/tf", STEPS),
        ("/tf_static", 1),
        ("/scan", STEPS - STEPS / 5),
        ("/particles", STEPS),
        ("/trajectory", 3),
        ("/map", 3),
        ("/landmarks", 3),
        ("/ground_truth", 1),
    ];
    assert_eq!(seen.len(), expect.len());
    for (topic, count) in expect {
        assert_eq!(n(topic), count, "{topic}");
        assert_eq!(counts[topic], count as u64, "{topic}");
    }

    let stamp = |k: usize| stamp_of(t_of(k)).unwrap();
    // Poses and tf: map → odom ∘ odom → base_link is the estimate.
    for (k, ((t, pose), (t2, tf))) in seen["/pose"].iter().zip(&seen["/tf"]).enumerate() {
        assert_eq!(*t, stamp(k).ns());
        assert_eq!(t, t2);
        let (s, frame, p) = d_pose_stamped(pose);
        assert_eq!((s, frame.as_str()), (stamp(k), MAP_FRAME));
        assert!((p.x - pose_of(k).x).abs() < 1e-12 && (p.y - pose_of(k).y).abs() < 1e-12);
        assert!(normalize(p.theta - pose_of(k).theta).abs() < 1e-12);
        let tf = crate::rosbag::msgs::tf_message("cdr", tf).unwrap();
        assert_eq!(tf.len(), 2);
        assert_eq!(
            (tf[0].parent.as_str(), tf[0].child.as_str()),
            ("map", "odom")
        );
        assert_eq!(
            (tf[1].parent.as_str(), tf[1].child.as_str()),
            ("odom", "base_link")
        );
        let base = tf[0].pose.compose(&tf[1].pose);
        assert!((base.x - pose_of(k).x).abs() < 1e-9 && (base.y - pose_of(k).y).abs() < 1e-9);
        assert!(normalize(base.theta - pose_of(k).theta).abs() < 1e-9);
        assert!((tf[1].pose.x - odom_of(k).x).abs() < 1e-12);
    }
    let mount = crate::rosbag::msgs::tf_message("cdr", &seen["/tf_static"][0].1).unwrap();
    assert_eq!(
        (mount[0].parent.as_str(), mount[0].child.as_str()),
        ("base_link", "laser")
    );
    assert!((mount[0].pose.theta - 0.05).abs() < 1e-12 && (mount[0].pose.x - 0.12).abs() < 1e-15);

    // Scans through the bag reader's own decoder: no return is +inf, the rest f32.
    let scan_steps: Vec<usize> = (0..STEPS).filter(|k| k % 5 != 4).collect();
    for (&k, (t, b)) in scan_steps.iter().zip(&seen["/scan"]) {
        assert_eq!(*t, stamp(k).ns());
        let m = crate::rosbag::msgs::laser_scan("cdr", b).unwrap();
        let s = scan(k);
        assert_eq!(m.header.frame_id, LASER_FRAME);
        assert_eq!(m.header.stamp_ns as u64, stamp(k).ns());
        assert_eq!(m.angle_min, f64::from(-FRAC_PI_2 as f32));
        assert_eq!(m.angle_increment, f64::from((PI / 180.0) as f32));
        assert_eq!(m.angle_max, f64::from(FRAC_PI_2 as f32));
        assert_eq!((m.range_min, m.range_max), (0.0, MAX_RANGE));
        assert_eq!(m.ranges.len(), s.ranges.len());
        for (r, &want) in m.ranges.iter().zip(&s.ranges) {
            if want >= MAX_RANGE {
                assert_eq!(*r, f64::INFINITY);
            } else {
                assert_eq!(*r, f64::from(want as f32));
            }
        }
    }

    for (k, (_, b)) in seen["/particles"].iter().enumerate() {
        let ps = d_pose_array(b);
        let want = particles_of(k);
        assert_eq!(ps.len(), want.len());
        for (p, w) in ps.iter().zip(&want) {
            assert!((p.x - w.pose.x).abs() < 1e-12 && (p.theta - w.pose.theta).abs() < 1e-12);
        }
    }

    // Trajectory snapshots hold the online estimates so far; the last is the run's path.
    let paths: Vec<_> = seen["/trajectory"].iter().map(|(_, b)| d_path(b)).collect();
    assert_eq!(paths[0].2.len(), 10);
    assert_eq!(paths[1].2.len(), 20);
    assert_eq!(paths[0].0, stamp(9));
    let (s, frame, last) = &paths[2];
    assert_eq!((*s, frame.as_str()), (stamp(STEPS - 1), MAP_FRAME));
    let traj = trajectory();
    assert_eq!(last.len(), traj.len());
    for (k, ((t, p), want)) in last.iter().zip(&traj).enumerate() {
        assert_eq!(*t, stamp(k));
        assert!((p.x - want.pose.x).abs() < 1e-12);
    }
    assert_eq!(d_path(&seen["/ground_truth"][0].1).2.len(), 7);

    // Maps: dimensions, resolution, origin and cells as given; the last is the final map.
    let snaps = [grid(9), grid(19), grid(99)];
    for ((t, b), want) in seen["/map"].iter().zip(&snaps) {
        let g = d_grid(b);
        assert_eq!(g.frame, MAP_FRAME);
        assert_eq!(g.stamp.ns(), *t);
        assert_eq!(g.load_time, g.stamp);
        assert_eq!((g.width, g.height), (40, 30));
        assert_eq!(g.resolution, f64::from(0.05f32));
        assert_eq!((g.origin.x, g.origin.y, g.origin.theta), (-3.2, -1.55, 0.0));
        assert_eq!(g.data, want.cells);
    }

    // Landmarks: DELETEALL, one ellipse per landmark, the means, the true landmarks.
    let marks: Vec<_> = seen["/landmarks"]
        .iter()
        .map(|(_, b)| d_markers(b))
        .collect();
    for (ms, want) in marks
        .iter()
        .zip([landmarks(9), landmarks(19), landmarks(99)])
    {
        assert_eq!((ms[0].action, ms[0].kind), (3, 0));
        let ellipses: Vec<_> = ms.iter().filter(|m| m.ns == "ellipses").collect();
        assert_eq!(ellipses.len(), want.len());
        for (e, l) in ellipses.iter().zip(&want) {
            assert_eq!((e.kind, e.action, e.id), (3, 0, l.id.0 as i32));
            assert_eq!((e.pose.x, e.pose.y), (l.mean.x, l.mean.y));
            // Both axis end points lie on the 95 % contour: (p − μ)ᵀ Σ⁻¹ (p − μ) = 5.991.
            let inv = l.covariance.try_inverse().unwrap();
            for (half, dir) in [
                (0.5 * e.scale[0], e.pose.theta),
                (0.5 * e.scale[1], e.pose.theta + FRAC_PI_2),
            ] {
                let d = slam_models::Vector2::new(half * dir.cos(), half * dir.sin());
                let m2 = (d.transpose() * inv * d)[(0, 0)];
                assert!((m2 - 5.991).abs() < 1e-3, "{m2}");
            }
        }
        let means = ms.iter().find(|m| m.ns == "landmarks").unwrap();
        assert_eq!(means.kind, 7);
        assert_eq!(means.points.len(), want.len());
        let truth = ms.iter().find(|m| m.ns == "true_landmarks").unwrap();
        assert_eq!(truth.points, vec![(0.0, 1.0), (2.1, 0.0)]);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

fn normalize(a: f64) -> f64 {
    slam_models::normalize_angle(a)
}

#[test]
fn same_run_same_bytes() {
    let dir = scratch("determinism");
    write_run(&dir.join("a.mcap"));
    write_run(&dir.join("b.mcap"));
    assert_eq!(
        std::fs::read(dir.join("a.mcap")).unwrap(),
        std::fs::read(dir.join("b.mcap")).unwrap()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_unfinished_run_leaves_no_file_and_bad_values_are_errors() {
    let dir = scratch("unfinished");
    let path = dir.join("run.mcap");
    let mut w = McapRunWriter::create(&path, McapRunOptions::default()).unwrap();
    w.step(&RunStep::new(1.0, Pose2::default())).unwrap();
    let e = w.step(&RunStep::new(-1.0, Pose2::default())).unwrap_err();
    assert!(e.to_string().contains("step 1: time -1 s"), "{e}");
    let e = w
        .step(&RunStep::new(f64::NAN, Pose2::default()))
        .unwrap_err();
    assert!(e.to_string().contains("[0, 2^31)"), "{e}");
    let mut bad = grid(0);
    bad.cells[7] = 101;
    let mut s = RunStep::new(2.0, Pose2::default());
    s.map = Some(&bad);
    let e = w.step(&s).unwrap_err();
    assert!(e.to_string().contains("map cell 7 holds 101"), "{e}");
    let mut short = grid(0);
    short.cells.pop();
    let mut s = RunStep::new(2.0, Pose2::default());
    s.map = Some(&short);
    assert!(w.step(&s).unwrap_err().to_string().contains("width·height"));
    assert!(dir.join("run.mcap.partial").exists());
    drop(w);
    assert!(!dir.join("run.mcap.partial").exists());
    assert!(!path.exists());
    let e = McapRunWriter::create(
        &path,
        McapRunOptions {
            snapshot_every: 0,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("at least 1"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn stamps_are_the_nearest_nanosecond() {
    // Epoch times of the Intel log, and small ones: the stamp is the f64 time rounded to
    // the nanosecond, checked against Rust's exact decimal formatting of the f64 (t·10⁹ in
    // f64 would be off by up to 64 ns at these magnitudes).
    for t in [
        976_052_890.244_09,
        976_052_857.338_1,
        1.5e9 + 0.123_456_789,
        12.000_000_5,
    ] {
        let s = stamp_of(t).unwrap();
        let text = format!("{t:.9}");
        let (sec, frac) = text.split_once('.').unwrap();
        assert_eq!(s.sec.to_string(), sec, "{t}");
        assert_eq!(format!("{:09}", s.nanosec), frac, "{t}");
    }
    let s = stamp_of(976_052_890.244_09).unwrap();
    assert!((s.nanosec as i64 - 244_090_000).abs() <= 60);
    let s = stamp_of(3.999_999_999_9).unwrap();
    assert_eq!((s.sec, s.nanosec), (4, 0));
    assert_eq!(stamp_of(0.0), Some(Stamp { sec: 0, nanosec: 0 }));
    for bad in [-1e-9, f64::NAN, f64::INFINITY, 2_147_483_648.0] {
        assert_eq!(stamp_of(bad), None, "{bad}");
    }
}

#[test]
fn ellipse_axes_of_a_known_covariance() {
    // Σ built from its axes: σ = 0.5 and 0.2 m along 30°.
    let phi = 30f64.to_radians();
    let (a, b, angle) = ellipse_95(&cov(0.5, 0.2, phi));
    assert!((a - 0.5 * 5.991_f64.sqrt()).abs() < 1e-4);
    assert!((b - 0.2 * 5.991_f64.sqrt()).abs() < 1e-4);
    assert!((angle - phi).abs() < 1e-12);
    // Isotropic: a circle.
    let (a, b, _) = ellipse_95(&cov(0.3, 0.3, 1.0));
    assert!((a - b).abs() < 1e-12);
}

#[test]
fn map_to_odom_carries_the_odometry_onto_the_estimate() {
    let (pose, odom) = (Pose2::new(3.0, -1.0, 2.9), Pose2::new(-7.0, 4.0, -2.0));
    let c = map_to_odom(&pose, &odom).compose(&odom);
    assert!((c.x - 3.0).abs() < 1e-12 && (c.y + 1.0).abs() < 1e-12);
    assert!(normalize(c.theta - 2.9).abs() < 1e-12);
}

#[test]
fn schemas_name_every_type_they_use_once() {
    for ty in [
        msgs::LASER_SCAN,
        msgs::TF_MESSAGE,
        msgs::OCCUPANCY_GRID,
        msgs::PATH,
        msgs::POSE_STAMPED,
        msgs::POSE_ARRAY,
        msgs::MARKER_ARRAY,
    ] {
        let s = msgs::schema(ty).unwrap();
        // Every complex field type has its section, exactly once.
        for line in s.lines() {
            let Some(t) = line.split_whitespace().next() else {
                continue;
            };
            let t = t.split('[').next().unwrap();
            if t.contains('/') && !line.contains('=') && t != ty.replace("/msg/", "/") {
                assert_eq!(s.matches(&format!("\nMSG: {t}\n")).count(), 1, "{ty}: {t}");
            }
        }
    }
    let m = msgs::schema(msgs::MARKER_ARRAY).unwrap();
    assert!(m.starts_with("visualization_msgs/Marker[] markers\n"));
    assert_eq!(m.matches("MSG: ").count(), 12);
}

fn stamp_ns(ns: i64) -> Stamp {
    Stamp {
        sec: (ns / 1_000_000_000) as i32,
        nanosec: (ns % 1_000_000_000) as u32,
    }
}

/// The encoder against an independent writer: the scans and transforms of the bag
/// reader's fixture (written by the Python `rosbags` package), decoded and encoded again,
/// give rosbags' bytes (but for the float32 `angle_max`, which rosbags computes from π in
/// float64 and this writer from the float32 angle_min and increment, and the quaternion,
/// recomputed from the decoded yaw: both to within rounding).
#[test]
fn encoder_matches_the_rosbags_writer() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/rosbag/intel-tf/intel-tf.mcap");
    let buf = std::fs::read(&path).unwrap();
    let (mut scans, mut tfs) = (0, 0);
    for m in mcap::MessageStream::new(&buf).unwrap() {
        let m = m.unwrap();
        let raw = &m.data[..];
        if m.channel.topic == "/scan" {
            let d = crate::rosbag::msgs::laser_scan("cdr", raw).unwrap();
            let s = LaserScan {
                angle_min: d.angle_min,
                angle_increment: d.angle_increment,
                ranges: d
                    .ranges
                    .iter()
                    .map(|&r| if r.is_finite() { r } else { d.range_max })
                    .collect(),
                max_range: d.range_max,
                sensor_pose: Pose2::default(),
            };
            let st = stamp_ns(d.header.stamp_ns);
            let mine = msgs::laser_scan(st, &d.header.frame_id, &s);
            assert_eq!(mine.len(), raw.len());
            // angle_max: body offset 8 + 4 + 8 ("laser\0" padded) + 4 = 24, plus the header.
            let at = 4 + 8 + 4 + 8 + 4;
            let f = |b: &[u8]| f32::from_le_bytes(b[at..at + 4].try_into().unwrap());
            assert!((f(&mine) - f(raw)).abs() <= f32::EPSILON * 2.0);
            assert_eq!(mine[..at], raw[..at]);
            assert_eq!(mine[at + 4..], raw[at + 4..]);
            scans += 1;
        } else {
            let d = crate::rosbag::msgs::tf_message("cdr", raw).unwrap();
            let ts: Vec<Transform<'_>> = d
                .iter()
                .map(|p| Transform {
                    stamp: stamp_ns(p.stamp_ns),
                    parent: &p.parent,
                    child: &p.child,
                    pose: p.pose,
                })
                .collect();
            let mine = msgs::tf_message(&ts);
            assert_eq!(mine.len(), raw.len());
            // The quaternion's z and w are the last 16 bytes of each one-transform message.
            let q = raw.len() - 16;
            assert_eq!(mine[..q], raw[..q]);
            for o in [q, q + 8] {
                let g = |b: &[u8]| f64::from_le_bytes(b[o..o + 8].try_into().unwrap());
                assert!((g(&mine) - g(raw)).abs() < 1e-15);
            }
            tfs += 1;
        }
    }
    assert_eq!(scans, 200);
    assert!(tfs > 3000);
}
