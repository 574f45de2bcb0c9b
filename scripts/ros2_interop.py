"""`cargo xtask eval ros2`: slam-rs's ROS 2 node against Eclipse Cyclone DDS, a DDS we did
not write (ROS 2's middleware `rmw_cyclonedds`).

Cyclone publishes the first N scans of a CARMEN log (`sensor_msgs/LaserScan` on `rt/scan`,
best effort) with their odometry (`nav_msgs/Odometry` on `rt/odom`) and the laser's mounting
(`rt/tf_static`), at the log's own pace times `--rate`; `slam ros2` maps them; a Cyclone
subscriber receives `rt/map` and `rt/tf`. Then, after Ctrl-C (SIGINT) to the node:

* the node's report (`node.json`): scans received, processed, skipped, latency, memory;
* the last `/map` Cyclone received against the node's saved map.yaml (size, origin,
  resolution) and against an offline `slam run` on the same messages: the scans the node
  processed, written as a CARMEN log holding exactly the values Cyclone sent (ranges
  rounded to float32, the yaw of the odometry quaternion as the node decodes it);
* the last `map → odom` Cyclone received against the offline run's final pose composed with
  the inverse of the final odometry.

* the node in the ROS 2 graph: the `rmw_dds_common/msg/ParticipantEntitiesInfo` it
  publishes on `ros_discovery_info` (what `ros2 node list` reads), decoded by Cyclone: the
  node's name and namespace, and its readers and writers among them those that matched
  Cyclone's (by the gids Cyclone's own discovery reports for them).

On a private DDS domain (100 + pid % 100). `cargo xtask eval ros2` runs it inside a network
namespace of its own (a veth pair, no route out), so nothing leaves the machine; plain
loopback does not work because RustDDS 0.13.1 ignores the loopback locators a peer announces
(`rtps_reader_proxy.rs` `not_loopback`, `transmit.rs`; docs/ros2.md). Exits non-zero on any failed check; prints the figures as JSON on
the last line.
"""

import argparse
import json
import math
import os
import re
import signal
import struct
import subprocess
import sys
import threading
import time

from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

import ros2_types as m
from slam_files import read_map_yaml, read_pgm, read_tum


def f32(x):
    """x rounded to float32, as a Python float (exact)."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


def read_flaser(path, n):
    """The first n FLASER records: (t, ranges, odom (x, y, theta))."""
    out = []
    with open(path) as f:
        for line in f:
            w = line.split()
            if not w or w[0] != "FLASER":
                continue
            k = int(w[1])
            ranges = [float(v) for v in w[2 : 2 + k]]
            rest = w[2 + k :]
            odom = tuple(float(v) for v in rest[3:6])
            t = float(rest[6])
            out.append((t, ranges, odom))
            if len(out) == n:
                break
    return out


def stamp_of(t):
    ns = int(round(t * 1e9))
    return ns, m.Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def quat(theta):
    return m.Quaternion(x=0.0, y=0.0, z=math.sin(0.5 * theta), w=math.cos(0.5 * theta))


def yaw(q):
    """The yaw the node's decoder takes from a quaternion (slam-io rosbag/msgs.rs, the same
    operations in the same order, so the same double)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), q.w * q.w + q.x * q.x - q.y * q.y - q.z * q.z)


def carmen_line(t, ranges, odom):
    r = " ".join(repr(v) for v in ranges)
    x, y, th = odom
    return f"FLASER {len(ranges)} {r} {x!r} {y!r} {th!r} {x!r} {y!r} {th!r} {t!r} cyclone {t!r}\n"


def robotlaser_line(t, ranges, odom, angle_min, inc, range_max):
    """A ROBOTLASER1 record: it states the beam geometry and the no-return range, so the
    offline run gets exactly the float32 values the node received."""
    r = " ".join(repr(v) for v in ranges)
    x, y, th = odom
    fov = inc * len(ranges)
    return (f"ROBOTLASER1 0 {angle_min!r} {fov!r} {inc!r} {range_max!r} 0 0 {len(ranges)} {r} 0 "
            f"{x!r} {y!r} {th!r} {x!r} {y!r} {th!r} 0 0 0 0 0 {t!r} cyclone {t!r}\n")


def compose(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap(a[2] + b[2]))


def inverse(a):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (-c * a[0] - s * a[1], s * a[0] - c * a[1], wrap(-a[2]))


def wrap(a):
    return math.atan2(math.sin(a), math.cos(a))


def read_tum_last(path):
    _, x, y, th = read_tum(path)[-1]
    return (x, y, th)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--slam", required=True)
    ap.add_argument("--log", required=True)
    ap.add_argument("--scans", type=int, default=300)
    ap.add_argument("--rate", type=float, default=1.0, help="replay speed, × real time")
    ap.add_argument("--filter", default="gridfast")
    ap.add_argument("--out", required=True)
    ap.add_argument("--domain", type=int, default=100 + os.getpid() % 100)
    ap.add_argument("--no-compare", action="store_true", help="no offline run (replays)")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    recs = read_flaser(a.log, a.scans)
    if len(recs) < a.scans:
        sys.exit(f"{a.log}: {len(recs)} FLASER records, {a.scans} asked for")

    # What Cyclone will send, as the node will decode it.
    sent = []
    for t, ranges, odom in recs:
        ns, _ = stamp_of(t)
        q = quat(odom[2])
        sent.append((ns, [f32(r) for r in ranges], (odom[0], odom[1], yaw(q))))
    sent_log = os.path.join(a.out, "sent.log")
    with open(sent_log, "w") as f:
        for ns, ranges, odom in sent:
            f.write(carmen_line(float(ns) * 1e-9, ranges, odom))
    # The no-return threshold slam-io infers for this log, as the reading it names.
    info = subprocess.run([a.slam, "info", sent_log], capture_output=True, text=True, check=True)
    shown = float(re.search(r"no return at or above ([\d.]+) m", info.stdout).group(1))
    every = sorted({r for _, rr, _ in sent for r in rr})
    range_max = min(every, key=lambda r: abs(r - shown))
    n = len(sent[0][1])
    angle_min = f32(-math.pi / 2)
    inc = f32(math.pi / n if n in (180, 360) else math.pi / (n - 1))

    env = dict(os.environ, ROS_DOMAIN_ID=str(a.domain))
    node_out = os.path.join(a.out, "node")
    node_log = open(os.path.join(a.out, "node.log"), "w")
    node = subprocess.Popen(
        [a.slam, "ros2", "--filter", a.filter, "--domain-id", str(a.domain), "--out", node_out,
         "--map-interval", "2", "--odom-topic", "/odom"],
        stdout=node_log, stderr=subprocess.STDOUT, env=env,
    )
    try:
        figures = run_cyclone(a, node, sent, range_max, angle_min, inc)
    finally:
        if node.poll() is None:
            node.kill()
    report = json.load(open(os.path.join(node_out, "node.json")))
    figures.update(
        received=report["received"], processed=report["processed"], skipped=report["skipped"],
        latency_ms=report["latency"], rss_mb=report["rss_mb"], sent=len(sent),
        rate=a.rate, decode_errors=report["decode_errors"], dropped=report["dropped"],
    )
    failures = []
    if report["decode_errors"]:
        failures.append(f"node: {report['decode_errors']} decode errors: {report['first_decode_error']}")
    if report["processed"] + report["skipped"] + report["no_odometry"] != report["received"]:
        failures.append("node: processed + skipped + no_odometry != received")
    if report["received"] < 0.95 * len(sent):
        failures.append(f"node received {report['received']} of {len(sent)} scans")
    # The map Cyclone received against the node's own saved map.
    res, origin = read_map_yaml(os.path.join(node_out, "map.yaml"))
    w, h, _ = read_pgm(os.path.join(node_out, "map.pgm"))
    g = figures.pop("last_map")
    if g is None:
        failures.append("Cyclone received no /map")
    else:
        figures["map"] = dict(width=g[0], height=g[1], resolution=g[2], origin=g[3:5])
        if (g[0], g[1]) != (w, h) or abs(g[2] - res) > 1e-6 or max(
            abs(g[3] - origin[0]), abs(g[4] - origin[1])
        ) > 1e-6:
            failures.append(f"/map {g} but map.yaml/pgm {w}x{h} res {res} origin {origin}")
    graph, matched = figures.pop("graph"), figures.pop("matched")
    if graph is None:
        failures.append("Cyclone received no ros_discovery_info node entry")
    else:
        figures["graph"] = dict(name=graph["name"], namespace=graph["namespace"],
                                readers=len(graph["readers"]), writers=len(graph["writers"]))
        if (graph["name"], graph["namespace"]) != ("slam", "/"):
            failures.append(f"ros_discovery_info names node {graph['namespace']}{graph['name']}")
        for what, gids in matched.items():
            have = graph["readers"] if "reader" in what else graph["writers"]
            if not gids or not all(g in have for g in gids):
                failures.append(f"ros_discovery_info: the node's {what} {gids} not in {have}")
    tf = figures.get("last_map_to_odom")
    if tf is None:
        failures.append("Cyclone received no map → odom on /tf")
    if not a.no_compare:
        # The offline run on exactly the scans the node processed.
        done = set(report["processed_stamps_ns"])
        proc_log = os.path.join(a.out, "processed.log")
        with open(proc_log, "w") as f:
            for ns, ranges, odom in sent:
                if ns in done:
                    f.write(robotlaser_line(float(ns) * 1e-9, ranges, odom, angle_min, inc,
                                            range_max))
        off = os.path.join(a.out, "offline")
        subprocess.run(
            [a.slam, "run", "--filter", a.filter, "--dataset", proc_log, "--out", off,
             "--quiet", "--force"], check=True, capture_output=True,
        )
        final = read_tum_last(os.path.join(off, "trajectory.tum"))
        last_odom = [o for ns, _, o in sent if ns in done][-1]
        expect = compose(final, inverse(last_odom))
        o_res, o_origin = read_map_yaml(os.path.join(off, "map.yaml"))
        o_w, o_h, _ = read_pgm(os.path.join(off, "map.pgm"))
        figures["offline_map_to_odom"] = expect
        figures["offline_map"] = dict(width=o_w, height=o_h, resolution=o_res, origin=o_origin[:2])
        if tf is not None:
            d = math.hypot(tf[0] - expect[0], tf[1] - expect[1])
            dth = abs(wrap(tf[2] - expect[2]))
            figures["map_to_odom_difference"] = dict(metres=d, radians=dth)
            if d > 0.05 or dth > 0.01:
                failures.append(f"map → odom {tf} vs offline {expect}: {d:.4f} m, {dth:.5f} rad")
        if g is not None and ((g[0], g[1]) != (o_w, o_h) or max(
            abs(g[3] - o_origin[0]), abs(g[4] - o_origin[1])
        ) > 1e-6):
            failures.append(f"/map {g[:5]} vs offline {o_w}x{o_h} origin {o_origin}")
    figures["failures"] = failures
    print(json.dumps(figures))
    sys.exit(1 if failures else 0)


def run_cyclone(a, node, sent, range_max, angle_min, inc):
    dp = DomainParticipant(a.domain)
    xcdr1 = Policy.DataRepresentation(use_cdrv0_representation=True)
    reliable = Policy.Reliability.Reliable(duration(seconds=1))
    q_scan = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(5), xcdr1)
    q_default = Qos(reliable, Policy.History.KeepLast(10), xcdr1)
    q_latched = Qos(reliable, Policy.History.KeepLast(1), Policy.Durability.TransientLocal, xcdr1)
    q_tf = Qos(reliable, Policy.History.KeepLast(100), xcdr1)
    scan_w = DataWriter(dp, Topic(dp, "rt/scan", m.LaserScan), qos=q_scan)
    odom_w = DataWriter(dp, Topic(dp, "rt/odom", m.Odometry), qos=q_default)
    static_w = DataWriter(dp, Topic(dp, "rt/tf_static", m.TFMessage), qos=q_latched)
    map_r = DataReader(dp, Topic(dp, "rt/map", m.OccupancyGrid), qos=q_latched)
    graph_r = DataReader(dp, Topic(dp, "ros_discovery_info", m.ParticipantEntitiesInfo),
                         qos=q_latched)
    tf_r = DataReader(dp, Topic(dp, "rt/tf", m.TFMessage), qos=q_tf)
    got = {"map": None, "maps": 0, "tf": None, "tfs": 0, "graph": None}
    done = threading.Event()

    def listen():
        while not done.is_set():
            for g in map_r.take(N=10):
                if not hasattr(g, "info"):
                    continue
                got["maps"] += 1
                i = g.info
                got["map"] = (i.width, i.height, i.resolution, i.origin.position.x,
                              i.origin.position.y, len(g.data))
            for info in graph_r.take(N=10):
                for n in getattr(info, "node_entities_info_seq", []):
                    got["graph"] = dict(
                        name=n.node_name, namespace=n.node_namespace,
                        participant=bytes(info.gid.data).hex(),
                        readers=[bytes(g.data).hex() for g in n.reader_gid_seq],
                        writers=[bytes(g.data).hex() for g in n.writer_gid_seq])
            for msg in tf_r.take(N=100):
                for t in getattr(msg, "transforms", []):
                    if t.header.frame_id == "map" and t.child_frame_id == "odom":
                        got["tfs"] += 1
                        r = t.transform.rotation
                        got["tf"] = (t.transform.translation.x, t.transform.translation.y,
                                     math.atan2(2.0 * r.w * r.z, r.w * r.w - r.z * r.z))
            time.sleep(0.005)

    listener = threading.Thread(target=listen)
    listener.start()
    # Discovery: wait until the node's scan reader has matched our writer.
    t0 = time.time()
    while scan_w.get_publication_matched_status().current_count == 0:
        if time.time() - t0 > 30 or node.poll() is not None:
            done.set()
            listener.join()
            raise SystemExit(f"the node's /scan reader never matched (node exit {node.poll()})")
        time.sleep(0.05)
    while odom_w.get_publication_matched_status().current_count == 0 and time.time() - t0 < 30:
        time.sleep(0.05)
    time.sleep(0.5)
    static_w.write(m.TFMessage(transforms=[m.TransformStamped(
        header=m.Header(stamp=m.Time(), frame_id="base_link"), child_frame_id="laser",
        transform=m.Transform())]))
    time.sleep(0.2)
    start = time.time()
    first = sent[0][0]
    for ns, ranges, odom in sent:
        due = start + (ns - first) * 1e-9 / a.rate
        time.sleep(max(0.0, due - time.time()))
        stamp = m.Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        q = quat(odom[2])
        odom_w.write(m.Odometry(
            header=m.Header(stamp=stamp, frame_id="odom"), child_frame_id="base_link",
            pose=m.PoseWithCovariance(pose=m.Pose(position=m.Point(x=odom[0], y=odom[1]),
                                                  orientation=q))))
        scan_w.write(m.LaserScan(
            header=m.Header(stamp=stamp, frame_id="laser"), angle_min=angle_min,
            angle_max=angle_min + (len(ranges) - 1) * inc, angle_increment=inc,
            range_min=0.0, range_max=range_max, ranges=ranges))
    replay_s = time.time() - start
    # The node's endpoints as Cyclone's own discovery sees them (RTPS GUIDs = ROS gids).
    def gids(entity, handles, data):
        return [getattr(data(h), "key").hex for h in handles]
    matched = {
        "scan reader": gids(scan_w, scan_w.get_matched_subscriptions(),
                            scan_w.get_matched_subscription_data),
        "map writer": gids(map_r, map_r.get_matched_publications(),
                           map_r.get_matched_publication_data),
        "tf writer": gids(tf_r, tf_r.get_matched_publications(),
                          tf_r.get_matched_publication_data),
    }
    time.sleep(3.0)
    node.send_signal(signal.SIGINT)
    try:
        node.wait(timeout=120)
    except subprocess.TimeoutExpired:
        node.kill()
        raise SystemExit("the node did not stop within 120 s of SIGINT")
    time.sleep(0.5)
    done.set()
    listener.join()
    if node.returncode != 0:
        raise SystemExit(f"the node exited with {node.returncode}")
    return {"replay_s": replay_s, "last_map": got["map"], "maps_received": got["maps"],
            "last_map_to_odom": got["tf"], "tf_received": got["tfs"], "graph": got["graph"],
            "matched": matched}


if __name__ == "__main__":
    main()
