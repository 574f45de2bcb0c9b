//! `--live` on `slam ros2` and `slam localize`: the program run as a process, a WebSocket
//! client (tungstenite's) connects with the Foxglove subprotocol, reads the `serverInfo` and
//! the `advertise`, subscribes to every channel and decodes one message of each by its
//! advertised ROS 2 type (the CDR layout of its .msg definition, read here field by field).

mod common;
use common::{bag_fixture, scratch, slam};
use slam_io::ros_msg;
use std::collections::HashMap;
use std::io::{BufRead, BufReader};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use tungstenite::client::IntoClientRequest;
use tungstenite::Message;

/// Starts `slam args…` with `--live 127.0.0.1:0`; returns the process and the address it
/// printed.
fn spawn_live(args: &[&str]) -> (Child, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_slam"))
        .args(args)
        .args(["--live", "127.0.0.1:0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let address = loop {
        let line = lines.next().expect("slam ended before serving").unwrap();
        if let Some(rest) = line.split("ws://").nth(1) {
            break rest.split_whitespace().next().unwrap().to_string();
        }
    };
    // Keep reading the output so that the program never blocks on a full pipe.
    std::thread::spawn(move || lines.for_each(drop));
    (child, address)
}

/// Ctrl-C to `child`; waits for it and checks it ended well.
fn interrupt(mut child: Child) {
    let pid = child.id().to_string();
    assert!(Command::new("kill")
        .args(["-INT", &pid])
        .status()
        .unwrap()
        .success());
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            assert!(status.success(), "{status}");
            return;
        }
        assert!(Instant::now() < deadline, "no exit 60 s after Ctrl-C");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// A channel of the advertise: topic and ROS type.
#[derive(Debug, Clone)]
struct Channel {
    topic: String,
    schema: String,
}

/// Connects to `address`, subscribes to every advertised channel and returns one message
/// of each (by topic), calling `poke` between reads (to publish the input) until every
/// channel has one or `timeout` passes.
fn watch(
    address: &str,
    timeout: Duration,
    mut poke: impl FnMut(),
) -> (HashMap<String, Channel>, HashMap<String, Vec<u8>>) {
    let mut req = format!("ws://{address}").into_client_request().unwrap();
    req.headers_mut().insert(
        "Sec-WebSocket-Protocol",
        "foxglove.websocket.v1".parse().unwrap(),
    );
    let stream = TcpStream::connect(address).unwrap();
    let (mut ws, resp) = tungstenite::client(req, stream).unwrap();
    assert_eq!(
        resp.headers()
            .get("Sec-WebSocket-Protocol")
            .map(|v| v.to_str().unwrap()),
        Some("foxglove.websocket.v1")
    );
    let text = |m: Message| match m {
        Message::Text(t) => serde_json::from_str::<serde_json::Value>(&t).unwrap(),
        other => panic!("a JSON text frame expected, got {other:?}"),
    };
    let info = text(ws.read().unwrap());
    assert_eq!(info["op"], "serverInfo", "{info}");
    let adv = text(ws.read().unwrap());
    assert_eq!(adv["op"], "advertise", "{adv}");
    let mut channels = HashMap::new();
    let mut subs = Vec::new();
    for (k, c) in adv["channels"].as_array().unwrap().iter().enumerate() {
        assert_eq!(c["encoding"], "cdr", "{c}");
        assert_eq!(c["schemaEncoding"], "ros2msg", "{c}");
        assert!(!c["schema"].as_str().unwrap().is_empty(), "{c}");
        let ch = Channel {
            topic: c["topic"].as_str().unwrap().to_string(),
            schema: c["schemaName"].as_str().unwrap().to_string(),
        };
        channels.insert(k as u32 + 100, ch);
        subs.push(serde_json::json!({"id": k as u32 + 100, "channelId": c["id"]}));
    }
    assert!(!channels.is_empty());
    let sub = serde_json::json!({"op": "subscribe", "subscriptions": subs});
    ws.send(Message::text(sub.to_string())).unwrap();
    ws.get_mut()
        .set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    let mut got: HashMap<String, Vec<u8>> = HashMap::new();
    let deadline = Instant::now() + timeout;
    while got.len() < channels.len() && Instant::now() < deadline {
        poke();
        match ws.read() {
            Ok(Message::Binary(b)) => {
                assert_eq!(b[0], 0x01, "Message Data opcode");
                let sub = u32::from_le_bytes(b[1..5].try_into().unwrap());
                let ch = channels
                    .get(&sub)
                    .expect("a frame of a subscription we made");
                got.entry(ch.topic.clone())
                    .or_insert_with(|| b[13..].to_vec());
            }
            Ok(_) => {}
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(e) => panic!("{e}"),
        }
    }
    let by_topic = channels
        .into_values()
        .map(|c| (c.topic.clone(), c))
        .collect();
    (by_topic, got)
}

/// A reader of XCDR1 little-endian bytes (alignment from the byte after the 4-byte header).
struct Cdr<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Cdr<'a> {
    fn new(b: &'a [u8]) -> Self {
        assert_eq!(&b[..2], &[0, 1], "CDR_LE encapsulation");
        Cdr { b, at: 4 }
    }
    fn take(&mut self, n: usize, align: usize) -> &'a [u8] {
        while (self.at - 4) % align != 0 {
            self.at += 1;
        }
        let s = &self.b[self.at..self.at + n];
        self.at += n;
        s
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take(4, 4).try_into().unwrap())
    }
    fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take(4, 4).try_into().unwrap())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take(8, 8).try_into().unwrap())
    }
    fn string(&mut self) -> String {
        let n = self.u32() as usize;
        let s = self.take(n, 1);
        assert_eq!(s[n - 1], 0, "string NUL");
        String::from_utf8(s[..n - 1].to_vec()).unwrap()
    }
    fn header(&mut self) -> String {
        self.u32();
        self.u32();
        self.string()
    }
    fn pose(&mut self) -> [f64; 7] {
        std::array::from_fn(|_| self.f64())
    }
    fn done(&self) {
        assert_eq!(self.at, self.b.len(), "trailing bytes");
    }
}

/// Decodes `msg` as `schema`; returns a one-line summary.
fn decode(schema: &str, msg: &[u8]) -> String {
    match schema {
        "sensor_msgs/msg/LaserScan" => {
            let s = ros_msg::decode_laser_scan(msg).unwrap();
            assert!(!s.ranges.is_empty());
            format!("scan of {} beams", s.ranges.len())
        }
        "tf2_msgs/msg/TFMessage" => {
            let t = ros_msg::decode_tf_message(msg).unwrap();
            assert!(!t.is_empty());
            format!("{} → {}", t[0].parent, t[0].child)
        }
        "nav_msgs/msg/OccupancyGrid" => {
            let mut c = Cdr::new(msg);
            let frame = c.header();
            c.u32();
            c.u32();
            let res = c.f32();
            let (w, h) = (c.u32() as usize, c.u32() as usize);
            c.pose();
            let n = c.u32() as usize;
            assert_eq!(n, w * h, "map cells");
            let cells = c.take(n, 1);
            assert!(cells
                .iter()
                .all(|&v| v as i8 == -1 || (0..=100).contains(&(v as i8))));
            c.done();
            assert!(res > 0.0 && w > 0 && h > 0);
            format!("map {w}x{h} in {frame}")
        }
        "nav_msgs/msg/Path" => {
            let mut c = Cdr::new(msg);
            c.header();
            let n = c.u32();
            for _ in 0..n {
                c.header();
                c.pose();
            }
            c.done();
            assert!(n > 0);
            format!("path of {n}")
        }
        "geometry_msgs/msg/PoseWithCovarianceStamped" => {
            let mut c = Cdr::new(msg);
            c.header();
            let p = c.pose();
            let cov: [f64; 36] = std::array::from_fn(|_| c.f64());
            c.done();
            assert!((p[3..].iter().map(|q| q * q).sum::<f64>() - 1.0).abs() < 1e-6);
            assert!(cov[0] >= 0.0 && cov[7] >= 0.0);
            "pose".into()
        }
        "geometry_msgs/msg/PoseArray" => {
            let mut c = Cdr::new(msg);
            c.header();
            let n = c.u32();
            for _ in 0..n {
                c.pose();
            }
            c.done();
            assert!(n > 0);
            format!("{n} particles")
        }
        other => panic!("unexpected type {other}"),
    }
}

/// Every advertised channel got a message and it decodes; returns the topics.
fn check_all(channels: &HashMap<String, Channel>, got: &HashMap<String, Vec<u8>>) -> Vec<String> {
    let mut missing: Vec<&String> = channels.keys().filter(|t| !got.contains_key(*t)).collect();
    missing.sort();
    assert!(missing.is_empty(), "no message on {missing:?}");
    let mut topics: Vec<String> = channels.keys().cloned().collect();
    topics.sort();
    for t in &topics {
        let summary = decode(&channels[t].schema, &got[t]);
        eprintln!("{t}: {summary}");
    }
    topics
}

#[test]
fn slam_ros2_live_serves_every_output() {
    let dir = scratch("live-ros2");
    let domain = 150 + std::process::id() % 80;
    let d = domain.to_string();
    let out = dir.join("node");
    let (child, address) = spawn_live(&[
        "ros2",
        "--domain-id",
        &d,
        "--odom-topic",
        "none",
        "--out",
        out.to_str().unwrap(),
    ]);
    // Scans of the bag fixture, published on /scan from a participant of our own.
    let (data, _) =
        slam_io::open_dataset(std::path::Path::new(&bag_fixture("intel-tf.bag")), None).unwrap();
    let slam_io::Dataset::Scan(data) = data else {
        panic!("laser data expected")
    };
    let scans: Vec<_> = data
        .records
        .iter()
        .filter_map(|r| r.scan.clone().map(|s| (r.t, s)))
        .collect();
    let dp = slam_ros::dds::Participant::new(domain as u16).unwrap();
    let w = dp
        .writer(
            "/scan",
            "sensor_msgs/msg/LaserScan",
            slam_ros::dds::Profile::SensorData,
        )
        .unwrap();
    let mut k = 0;
    let mut last = Instant::now() - Duration::from_secs(1);
    let (channels, got) = watch(&address, Duration::from_secs(90), || {
        if last.elapsed() >= Duration::from_millis(100) && k < scans.len() {
            let (t, s) = &scans[k];
            let msg = ros_msg::encode_laser_scan(ros_msg::stamp(*t).unwrap(), "laser", s);
            slam_ros::dds::write(&w, "/scan", msg).unwrap();
            k += 1;
            last = Instant::now();
        }
    });
    let topics = check_all(&channels, &got);
    for t in ["/map", "/tf", "/pose", "/trajectory", "/particles", "/scan"] {
        assert!(
            topics.iter().any(|x| x == t),
            "{t} not advertised: {topics:?}"
        );
    }
    // Laser only: no robot publishes `odom → base_link`, so the node publishes it (the
    // laser odometry) beside `map → odom`, and the tree reaches the robot.
    let tf = ros_msg::decode_tf_message(&got["/tf"]).unwrap();
    let pairs: Vec<(&str, &str)> = tf
        .iter()
        .map(|t| (t.parent.as_str(), t.child.as_str()))
        .collect();
    assert_eq!(pairs, [("map", "odom"), ("odom", "base_link")], "{pairs:?}");
    interrupt(child);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("node.json")).unwrap()).unwrap();
    assert!(report["processed"].as_u64().unwrap() >= 1, "{report}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn slam_localize_live_serves_every_output() {
    let dir = scratch("live-localize");
    let bag = bag_fixture("intel-tf.bag");
    let map = dir.join("map");
    let (r, text) = slam(&[
        "run",
        "--filter",
        "known-poses",
        "--dataset",
        &bag,
        "--out",
        map.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(r.is_ok(), "{r:?} {text}");
    // Few particles: the test is about the view, not the localization.
    let config = dir.join("mcl.toml");
    std::fs::write(&config, "[kld]\nmin-particles = 50\nmax-particles = 200\n").unwrap();
    let (child, address) = spawn_live(&[
        "localize",
        "--config",
        config.to_str().unwrap(),
        "--map",
        map.join("map.yaml").to_str().unwrap(),
        "--dataset",
        &bag,
        "--out",
        dir.join("loc").to_str().unwrap(),
        "--initial-pose",
        "0,0,0",
        "--live-hold",
    ]);
    let (channels, got) = watch(&address, Duration::from_secs(60), || {});
    let topics = check_all(&channels, &got);
    for t in ["/map", "/pose", "/particles"] {
        assert!(
            topics.iter().any(|x| x == t),
            "{t} not advertised: {topics:?}"
        );
    }
    // Held after the localization (its files written), until Ctrl-C.
    let done = dir.join("loc/metrics.json");
    let deadline = Instant::now() + Duration::from_secs(120);
    while !done.is_file() {
        assert!(Instant::now() < deadline, "the localization did not finish");
        std::thread::sleep(Duration::from_millis(100));
    }
    interrupt(child);
    assert!(dir.join("loc/trajectory.tum").is_file());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `slam ros2` stopped by SIGTERM (what systemd and `ros2 launch`'s escalation send) before
/// any scan arrived: it exits 0 and writes node.json with 0 scans processed, and no map or
/// trajectory (there is none yet), instead of failing on an empty grid.
#[test]
fn slam_ros2_stops_on_sigterm_before_any_scan() {
    let dir = scratch("ros2-sigterm");
    let out = dir.join("node");
    let domain = (230 + std::process::id() % 2).to_string();
    let mut child = Command::new(env!("CARGO_BIN_EXE_slam"))
        .args([
            "ros2",
            "--domain-id",
            &domain,
            "--out",
            out.to_str().unwrap(),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let pid = child.id().to_string();
    assert!(Command::new("kill")
        .args(["-TERM", &pid])
        .status()
        .unwrap()
        .success());
    let deadline = Instant::now() + Duration::from_secs(60);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < deadline, "no exit 60 s after SIGTERM");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success(), "{status}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("node.json")).unwrap()).unwrap();
    assert_eq!(report["processed"], 0);
    assert!(!out.join("map.pgm").exists());
}
