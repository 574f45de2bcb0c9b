//! `--live [ADDRESS]`: the run served over the Foxglove WebSocket protocol
//! (`foxglove.websocket.v1`, <https://github.com/foxglove/ws-protocol>), so that Foxglove
//! (Studio or the web app: *Open connection → Foxglove WebSocket → ws://ADDRESS*) shows it
//! while it happens.
//!
//! The server implements the protocol's core, nothing optional:
//!
//! * the WebSocket handshake must offer the subprotocol `foxglove.websocket.v1`;
//! * on connecting, the server sends `serverInfo` (no capabilities) and one `advertise` with
//!   a channel per output ([`Out`]): `encoding` `cdr`, `schemaEncoding` `ros2msg`, the
//!   message definition with its dependencies as `schema` (Foxglove decodes and draws the ROS
//!   types itself);
//! * the client's `subscribe` (`{"op":"subscribe","subscriptions":[{"id","channelId"}]}`)
//!   and `unsubscribe` (`{"op":"unsubscribe","subscriptionIds":[…]}`) are honoured;
//! * each message goes to its subscribers as a binary frame: opcode `0x01`, the
//!   subscription id (`uint32` LE), the log time (`uint64` LE, ns) and the CDR message.
//!
//! A new subscription first receives the channel's latest message (so the map and the
//! trajectory appear at once). Each client has a bounded queue ([`CLIENT_QUEUE`] frames): a
//! client that reads too slowly loses frames (counted in [`LiveServer::dropped`]) and never
//! slows the filter down. The map and the trajectory are not queued: a client is sent their
//! latest message whenever it is free, so the last ones always arrive.

use crate::error::RosError;
use crate::outputs::Out;
use std::collections::HashMap;
use std::io::ErrorKind;
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;
use tungstenite::handshake::server::{ErrorResponse, Request, Response};
use tungstenite::{Message, WebSocket};

/// The WebSocket subprotocol of the Foxglove protocol.
pub const SUBPROTOCOL: &str = "foxglove.websocket.v1";
/// The address `--live` serves on when none is given (loopback only: pass `0.0.0.0:8765`
/// to serve the robot's network).
pub const DEFAULT_ADDRESS: &str = "127.0.0.1:8765";
/// Frames queued per client before the oldest new ones are dropped.
pub const CLIENT_QUEUE: usize = 256;

/// One frame on its way to a client: subscription id, log time (ns), message.
type Frame = (u32, u64, Arc<Vec<u8>>);
/// A channel's latest message: log time (ns) and bytes.
type Latest = (u64, Arc<Vec<u8>>);

/// One connected client, as the publishing side sees it.
struct Client {
    /// Channel id → subscription id.
    subs: Arc<Mutex<HashMap<u32, u32>>>,
    tx: SyncSender<Frame>,
    /// Latched channels with a message the client has not been sent yet.
    dirty: Arc<Mutex<Vec<u32>>>,
    gone: Arc<AtomicBool>,
}

/// The channels whose latest message alone matters (the map and the trajectory): they are
/// never queued nor dropped; the client is sent the latest when it is free, so the final
/// map and trajectory always arrive.
fn latched(out: Out) -> bool {
    matches!(out, Out::Map | Out::Trajectory)
}

struct Shared {
    /// Topic of each channel, by channel id (ids 1…).
    channels: Vec<(u32, Out, String)>,
    clients: Mutex<Vec<Client>>,
    /// The latest message of each channel: log time and bytes.
    latest: Mutex<HashMap<u32, Latest>>,
    stop: AtomicBool,
    dropped: AtomicU64,
    sent: AtomicU64,
}

/// A Foxglove WebSocket server of the outputs ([`Out`]), each on its topic.
pub struct LiveServer {
    shared: Arc<Shared>,
    address: SocketAddr,
    accept: Option<JoinHandle<()>>,
}

impl LiveServer {
    /// Listens on `address` (`HOST:PORT`; port 0 picks a free one, see
    /// [`LiveServer::address`]) and advertises one channel per output on `topics(out)`.
    pub fn start(address: &str, topics: impl Fn(Out) -> String) -> Result<Self, RosError> {
        let listen = |source| RosError::Listen {
            address: address.to_string(),
            source,
        };
        let listener = TcpListener::bind(address).map_err(listen)?;
        listener.set_nonblocking(true).map_err(listen)?;
        let local = listener.local_addr().map_err(listen)?;
        let channels = Out::ALL
            .iter()
            .enumerate()
            .map(|(i, &o)| (i as u32 + 1, o, topics(o)))
            .collect();
        let shared = Arc::new(Shared {
            channels,
            clients: Mutex::new(Vec::new()),
            latest: Mutex::new(HashMap::new()),
            stop: AtomicBool::new(false),
            dropped: AtomicU64::new(0),
            sent: AtomicU64::new(0),
        });
        let s = Arc::clone(&shared);
        let accept = std::thread::Builder::new()
            .name("live-accept".into())
            .spawn(move || accept_loop(listener, s))
            .map_err(listen)?;
        Ok(LiveServer {
            shared,
            address: local,
            accept: Some(accept),
        })
    }

    /// The address served.
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// Sends `message` (CDR bytes) of output `out`, logged at `log_time_ns`, to its
    /// subscribers, and keeps it as the channel's latest.
    pub fn publish(&self, out: Out, log_time_ns: u64, message: Vec<u8>) {
        let Some(&(id, _, _)) = self.shared.channels.iter().find(|(_, o, _)| *o == out) else {
            return;
        };
        let latched = latched(out);
        let message = Arc::new(message);
        if let Ok(mut latest) = self.shared.latest.lock() {
            latest.insert(id, (log_time_ns, Arc::clone(&message)));
        }
        let Ok(mut clients) = self.shared.clients.lock() else {
            return;
        };
        clients.retain(|c| !c.gone.load(Ordering::Relaxed));
        for c in clients.iter() {
            let sub = c.subs.lock().ok().and_then(|s| s.get(&id).copied());
            if latched {
                if let (Some(_), Ok(mut d)) = (sub, c.dirty.lock()) {
                    if !d.contains(&id) {
                        d.push(id);
                    }
                }
                continue;
            }
            if let Some(sub) = sub {
                match c.tx.try_send((sub, log_time_ns, Arc::clone(&message))) {
                    Ok(()) => {}
                    Err(TrySendError::Full(_)) => {
                        self.shared.dropped.fetch_add(1, Ordering::Relaxed);
                    }
                    Err(TrySendError::Disconnected(_)) => c.gone.store(true, Ordering::Relaxed),
                }
            }
        }
    }

    /// Frames dropped because a client's queue was full.
    pub fn dropped(&self) -> u64 {
        self.shared.dropped.load(Ordering::Relaxed)
    }

    /// Frames written to clients.
    pub fn sent(&self) -> u64 {
        self.shared.sent.load(Ordering::Relaxed)
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.shared
            .clients
            .lock()
            .map(|c| c.iter().filter(|c| !c.gone.load(Ordering::Relaxed)).count())
            .unwrap_or(0)
    }
}

impl Drop for LiveServer {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.accept.take() {
            let _ = h.join();
        }
    }
}

fn accept_loop(listener: TcpListener, shared: Arc<Shared>) {
    let mut workers = Vec::new();
    while !shared.stop.load(Ordering::Relaxed) {
        match listener.accept() {
            Ok((stream, _)) => {
                let (tx, rx) = sync_channel(CLIENT_QUEUE);
                let subs = Arc::new(Mutex::new(HashMap::new()));
                let dirty = Arc::new(Mutex::new(Vec::new()));
                let gone = Arc::new(AtomicBool::new(false));
                if let Ok(mut clients) = shared.clients.lock() {
                    clients.push(Client {
                        subs: Arc::clone(&subs),
                        tx,
                        dirty: Arc::clone(&dirty),
                        gone: Arc::clone(&gone),
                    });
                }
                let s = Arc::clone(&shared);
                if let Ok(h) = std::thread::Builder::new()
                    .name("live-client".into())
                    .spawn(move || {
                        // A client that breaks the protocol or hangs up is only dropped.
                        let _ = serve_client(stream, &s, &subs, &dirty, rx);
                        gone.store(true, Ordering::Relaxed);
                    })
                {
                    workers.push(h);
                }
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(_) => std::thread::sleep(Duration::from_millis(20)),
        }
    }
    for h in workers {
        let _ = h.join();
    }
}

/// The `serverInfo` and `advertise` messages.
fn hello(shared: &Shared) -> [String; 2] {
    let info = serde_json::json!({
        "op": "serverInfo",
        "name": "slam-rs",
        "capabilities": [],
        "supportedEncodings": [],
        "metadata": {},
        "sessionId": format!("{}", std::process::id()),
    });
    let channels: Vec<_> = shared
        .channels
        .iter()
        .map(|(id, out, topic)| {
            serde_json::json!({
                "id": id,
                "topic": topic,
                "encoding": "cdr",
                "schemaName": out.ros_type(),
                "schema": slam_io::ros_msg::schema(out.ros_type()).unwrap_or_default(),
                "schemaEncoding": "ros2msg",
            })
        })
        .collect();
    let advertise = serde_json::json!({"op": "advertise", "channels": channels});
    [info.to_string(), advertise.to_string()]
}

/// The binary `Message Data` frame.
fn data_frame(sub: u32, log_time_ns: u64, message: &[u8]) -> Vec<u8> {
    let mut f = Vec::with_capacity(13 + message.len());
    f.push(0x01);
    f.extend_from_slice(&sub.to_le_bytes());
    f.extend_from_slice(&log_time_ns.to_le_bytes());
    f.extend_from_slice(message);
    f
}

fn serve_client(
    stream: TcpStream,
    shared: &Shared,
    subs: &Mutex<HashMap<u32, u32>>,
    dirty: &Mutex<Vec<u32>>,
    rx: Receiver<Frame>,
) -> Result<(), Box<dyn std::error::Error>> {
    stream.set_nonblocking(false)?;
    stream.set_read_timeout(Some(Duration::from_secs(5)))?;
    // tungstenite's callback type fixes the error type (an HTTP response).
    #[allow(clippy::result_large_err)]
    let callback = |req: &Request, mut resp: Response| -> Result<Response, ErrorResponse> {
        let offered = req
            .headers()
            .get_all("Sec-WebSocket-Protocol")
            .iter()
            .filter_map(|v| v.to_str().ok())
            .flat_map(|v| v.split(',').map(str::trim))
            .any(|p| p == SUBPROTOCOL);
        if !offered {
            let mut r = ErrorResponse::new(Some(format!("subprotocol {SUBPROTOCOL} required")));
            *r.status_mut() = tungstenite::http::StatusCode::BAD_REQUEST;
            return Err(r);
        }
        resp.headers_mut().insert(
            "Sec-WebSocket-Protocol",
            tungstenite::http::HeaderValue::from_static(SUBPROTOCOL),
        );
        Ok(resp)
    };
    let mut ws: WebSocket<TcpStream> = tungstenite::accept_hdr(stream, callback)?;
    ws.get_ref()
        .set_read_timeout(Some(Duration::from_millis(10)))?;
    for text in hello(shared) {
        ws.send(Message::text(text))?;
    }
    loop {
        if shared.stop.load(Ordering::Relaxed) {
            let _ = ws.close(None);
            let _ = ws.flush();
            return Ok(());
        }
        match ws.read() {
            Ok(Message::Text(t)) => {
                let catch_up = handle_request(t.as_str(), subs);
                // A new subscription starts with its channel's latest message.
                for (channel, sub) in catch_up {
                    send_latest(&mut ws, shared, channel, sub)?;
                }
            }
            Ok(Message::Close(_)) => return Ok(()),
            Ok(_) => {}
            Err(tungstenite::Error::Io(e))
                if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(e) => return Err(e.into()),
        }
        let due: Vec<u32> = dirty
            .lock()
            .map(|mut d| std::mem::take(&mut *d))
            .unwrap_or_default();
        for channel in due {
            let sub = subs.lock().ok().and_then(|s| s.get(&channel).copied());
            if let Some(sub) = sub {
                send_latest(&mut ws, shared, channel, sub)?;
            }
        }
        while let Ok((sub, ts, msg)) = rx.try_recv() {
            // The client may have unsubscribed since the frame was queued.
            let live = subs
                .lock()
                .map(|s| s.values().any(|v| *v == sub))
                .unwrap_or(false);
            if live {
                ws.write(Message::binary(data_frame(sub, ts, &msg)))?;
                shared.sent.fetch_add(1, Ordering::Relaxed);
            }
        }
        match ws.flush() {
            Ok(()) => {}
            Err(tungstenite::Error::Io(e))
                if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(e) => return Err(e.into()),
        }
    }
}

/// Writes `channel`'s latest message, if any, for subscription `sub`.
fn send_latest(
    ws: &mut WebSocket<TcpStream>,
    shared: &Shared,
    channel: u32,
    sub: u32,
) -> Result<(), tungstenite::Error> {
    let latest = shared
        .latest
        .lock()
        .ok()
        .and_then(|l| l.get(&channel).cloned());
    if let Some((ts, msg)) = latest {
        ws.write(Message::binary(data_frame(sub, ts, &msg)))?;
        shared.sent.fetch_add(1, Ordering::Relaxed);
    }
    Ok(())
}

/// Applies a client's `subscribe` / `unsubscribe`; returns the new (channel, subscription)
/// pairs. Other operations and malformed requests are ignored (the protocol's server may
/// answer them with a status message; this one says nothing).
fn handle_request(text: &str, subs: &Mutex<HashMap<u32, u32>>) -> Vec<(u32, u32)> {
    let Ok(v) = serde_json::from_str::<serde_json::Value>(text) else {
        return Vec::new();
    };
    let Ok(mut subs) = subs.lock() else {
        return Vec::new();
    };
    let mut added = Vec::new();
    match v.get("op").and_then(|o| o.as_str()) {
        Some("subscribe") => {
            for s in v["subscriptions"].as_array().into_iter().flatten() {
                let (Some(id), Some(channel)) = (s["id"].as_u64(), s["channelId"].as_u64()) else {
                    continue;
                };
                let (Ok(id), Ok(channel)) = (u32::try_from(id), u32::try_from(channel)) else {
                    continue;
                };
                subs.insert(channel, id);
                added.push((channel, id));
            }
        }
        Some("unsubscribe") => {
            for id in v["subscriptionIds"].as_array().into_iter().flatten() {
                if let Some(id) = id.as_u64() {
                    subs.retain(|_, s| u64::from(*s) != id);
                }
            }
        }
        _ => {}
    }
    added
}

/// The live view of a run over a file (`slam run --live`): after each record, the step's
/// outputs ([`crate::outputs::step_messages`] with `odom → base` and the scan), the map at
/// most once per [`RunView::MAP_EVERY`] of wall time and the trajectory at most once per
/// [`RunView::TRAJECTORY_EVERY`], and both after the last record.
pub struct RunView {
    server: LiveServer,
    frames: crate::outputs::Frames,
    last_map: Option<std::time::Instant>,
    last_trajectory: Option<std::time::Instant>,
}

impl RunView {
    /// Wall time between two maps.
    pub const MAP_EVERY: Duration = Duration::from_secs(1);
    /// Wall time between two trajectories.
    pub const TRAJECTORY_EVERY: Duration = Duration::from_millis(250);

    /// A view served by `server`.
    pub fn new(server: LiveServer) -> Self {
        RunView {
            server,
            frames: crate::outputs::Frames::default(),
            last_map: None,
            last_trajectory: None,
        }
    }

    /// The server.
    pub fn server(&self) -> &LiveServer {
        &self.server
    }

    /// Publishes the state after `record`; `last` forces the map and the trajectory.
    pub fn step(
        &mut self,
        record: &slam_models::ScanRecord,
        filter: &dyn slam_models::ScanSlam,
        last: bool,
    ) {
        let due = |at: Option<std::time::Instant>, every| at.is_none_or(|a| a.elapsed() >= every);
        let map = last || due(self.last_map, Self::MAP_EVERY);
        let trajectory = last || due(self.last_trajectory, Self::TRAJECTORY_EVERY);
        let now = std::time::Instant::now();
        if map {
            self.last_map = Some(now);
        }
        if trajectory {
            self.last_trajectory = Some(now);
        }
        // A time outside builtin_interfaces/Time's range is stamped 0.
        let stamp = slam_io::ros_msg::stamp(record.t)
            .unwrap_or(slam_io::ros_msg::Stamp { sec: 0, nanosec: 0 });
        let include = crate::outputs::Include {
            map,
            trajectory,
            odom_tf: true,
            scan: record.scan.as_ref(),
        };
        for (out, bytes) in
            crate::outputs::step_messages(stamp, filter, &record.odometry, &self.frames, include)
        {
            self.server.publish(out, stamp.ns(), bytes);
        }
    }
}

impl RunView {
    /// Publishes a localization step (`slam localize --live`): `pose` and `cloud` in the
    /// map frame after `record`, with `map → odom`, `odom → base` and the scan; `map` (the
    /// fixed map localized on) goes out once, with the first step; `trajectory` (the
    /// estimates so far) every [`RunView::TRAJECTORY_EVERY`] of wall time.
    pub fn localize_step(
        &mut self,
        record: &slam_models::ScanRecord,
        pose: slam_models::Pose2,
        cloud: &[slam_models::WeightedPose],
        map: &slam_models::GridMap,
        trajectory: &[slam_models::TimedPose],
    ) {
        use slam_io::ros_msg::{self, Transform};
        let stamp = ros_msg::stamp(record.t).unwrap_or(ros_msg::Stamp { sec: 0, nanosec: 0 });
        let f = &self.frames;
        let mut out = Vec::new();
        if self.last_map.is_none() {
            self.last_map = Some(std::time::Instant::now());
            out.push((Out::Map, ros_msg::encode_occupancy_grid(stamp, &f.map, map)));
        }
        let tf = [
            Transform {
                stamp,
                parent: &f.map,
                child: &f.odom,
                pose: crate::outputs::map_to_odom(&pose, &record.odometry),
            },
            Transform {
                stamp,
                parent: &f.odom,
                child: &f.base,
                pose: record.odometry,
            },
        ];
        out.push((Out::Tf, ros_msg::encode_tf_message(&tf)));
        if self
            .last_trajectory
            .is_none_or(|a| a.elapsed() >= Self::TRAJECTORY_EVERY)
        {
            self.last_trajectory = Some(std::time::Instant::now());
            out.push((
                Out::Trajectory,
                crate::outputs::path_message(stamp, trajectory, f),
            ));
        }
        let cov = crate::convert::cloud_covariance(cloud).unwrap_or([[0.0; 3]; 3]);
        out.push((
            Out::Pose,
            ros_msg::encode_pose_with_covariance(stamp, &f.map, &pose, &cov),
        ));
        let poses: Vec<slam_models::Pose2> = cloud.iter().map(|p| p.pose).collect();
        out.push((
            Out::Particles,
            ros_msg::encode_pose_array(stamp, &f.map, &poses),
        ));
        if let Some(scan) = &record.scan {
            let mount = [Transform {
                stamp,
                parent: &f.base,
                child: &f.laser,
                pose: scan.sensor_pose,
            }];
            out.push((Out::TfStatic, ros_msg::encode_tf_message(&mount)));
            out.push((Out::Scan, ros_msg::encode_laser_scan(stamp, &f.laser, scan)));
        }
        for (o, bytes) in out {
            self.server.publish(o, stamp.ns(), bytes);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_frames_follow_the_protocol_layout() {
        let f = data_frame(7, 0x0102_0304_0506_0708, &[0xAA, 0xBB]);
        assert_eq!(f, vec![1, 7, 0, 0, 0, 8, 7, 6, 5, 4, 3, 2, 1, 0xAA, 0xBB]);
    }

    #[test]
    fn subscriptions_are_added_and_removed() {
        let subs = Mutex::new(HashMap::new());
        let added = handle_request(
            r#"{"op":"subscribe","subscriptions":[{"id":0,"channelId":3},{"id":1,"channelId":1}]}"#,
            &subs,
        );
        assert_eq!(added, vec![(3, 0), (1, 1)]);
        handle_request(r#"{"op":"unsubscribe","subscriptionIds":[0]}"#, &subs);
        assert_eq!(subs.lock().unwrap().len(), 1);
        assert!(handle_request("not json", &subs).is_empty());
        assert!(handle_request(
            r#"{"op":"subscribe","subscriptions":[{"id":-1,"channelId":1}]}"#,
            &subs
        )
        .is_empty());
    }
}
