"""`cargo xtask eval ros2`: `slam run --live` read by an independent Foxglove WebSocket
client: the `websockets` package speaking the published protocol
(https://github.com/foxglove/ws-protocol, `foxglove.websocket.v1`), every message decoded
by Eclipse Cyclone DDS's own CDR deserialiser with the ROS 2 types of ros2_types.py.

Runs `slam run --filter F --dataset D --live ADDR --live-hold`, connects, subscribes to
every advertised channel, and once the run's outputs are in place (metrics.json) checks:

* the server offered the subprotocol and sent serverInfo, then advertise;
* every advertised channel is `cdr` with a `ros2msg` schema, delivered at least one message,
  and every message decoded (no exception, no bytes left over);
* the last /map against the run's map.yaml + map.pgm: size, resolution, origin, and every
  cell's map_saver pixel;
* the last /trajectory against trajectory.tum: the same poses at the same times.

Prints the figures as JSON on the last line; exits non-zero on a failed check.
"""

import argparse
import json
import math
import os
import signal
import socket
import struct
import subprocess
import sys
import time

from websockets.sync.client import connect

import ros2_types as m
from slam_files import read_map_yaml, read_pgm, read_tum, trinary


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--slam", required=True)
    ap.add_argument("--dataset", required=True)
    ap.add_argument("--filter", default="gridfast")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    addr = f"127.0.0.1:{free_port()}"
    for f in ("metrics.json",):
        if os.path.exists(os.path.join(a.out, f)):
            os.remove(os.path.join(a.out, f))
    run = subprocess.Popen(
        [a.slam, "run", "--filter", a.filter, "--dataset", a.dataset, "--out", a.out,
         "--force", "--quiet", "--live", addr, "--live-hold"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )
    failures = []
    try:
        ws = None
        t0 = time.time()
        while ws is None:
            try:
                ws = connect(f"ws://{addr}", subprotocols=["foxglove.websocket.v1"],
                             max_size=None, open_timeout=2)
            except OSError:
                if time.time() - t0 > 60 or run.poll() is not None:
                    sys.exit(f"could not connect to {addr} (slam exit {run.poll()})")
                time.sleep(0.05)
        with ws:
            check_stream(a, ws, run, t0, failures, figures := {})
    finally:
        run.send_signal(signal.SIGINT)
        try:
            out, _ = run.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            run.kill()
            out = ""
    if run.returncode != 0:
        failures.append(f"slam run exited {run.returncode}: {out[-500:]}")
    figures["failures"] = failures
    print(json.dumps(figures))
    sys.exit(1 if failures else 0)


def check_stream(a, ws, run, t0, failures, figures):
    if ws.subprotocol != "foxglove.websocket.v1":
        failures.append(f"subprotocol {ws.subprotocol!r}")
    info = json.loads(ws.recv(timeout=10))
    adv = json.loads(ws.recv(timeout=10))
    if info.get("op") != "serverInfo" or adv.get("op") != "advertise":
        failures.append(f"first messages {info.get('op')}, {adv.get('op')}")
    channels = {c["id"]: c for c in adv["channels"]}
    for c in channels.values():
        if c["encoding"] != "cdr" or c["schemaEncoding"] != "ros2msg" or not c["schema"]:
            failures.append(f"channel {c['topic']}: {c['encoding']}/{c['schemaEncoding']}")
    subs = {i: cid for i, cid in enumerate(channels)}
    ws.send(json.dumps({"op": "subscribe", "subscriptions": [
        {"id": i, "channelId": cid} for i, cid in subs.items()]}))
    counts = {c["topic"]: 0 for c in channels.values()}
    last = {}
    # The run is over when its outputs are in place (metrics.json is written last); the
    # stream is drained when nothing has come for 2 s after that (the server holds the
    # last state and sends nothing new).
    quiet_since = time.time()
    while True:
        done = os.path.exists(os.path.join(a.out, "metrics.json"))
        if done and time.time() - quiet_since > 2.0:
            break
        if time.time() - t0 > 600:
            failures.append("the run did not finish within 600 s")
            break
        try:
            msg = ws.recv(timeout=0.2)
        except TimeoutError:
            continue
        quiet_since = time.time()
        if isinstance(msg, str):
            continue
        op, sub, ts = struct.unpack_from("<BIQ", msg, 0)
        if op != 1:
            continue
        ch = channels[subs[sub]]
        payload = msg[13:]
        try:
            value = m.BY_ROS_NAME[ch["schemaName"]].deserialize(payload)
        except Exception as e:  # noqa: BLE001 - any decoding failure is a finding
            failures.append(f"{ch['topic']}: message did not decode: {e}")
            continue
        counts[ch["topic"]] += 1
        last[ch["topic"]] = value
    figures["messages"] = counts
    g = last.get("/map")
    if g is not None:
        res, origin = read_map_yaml(os.path.join(a.out, "map.yaml"))
        w, h, pixels = read_pgm(os.path.join(a.out, "map.pgm"))
        i = g.info
        if (i.width, i.height) != (w, h) or abs(i.resolution - res) > 1e-6 or max(
            abs(i.origin.position.x - origin[0]), abs(i.origin.position.y - origin[1])
        ) > 1e-6:
            failures.append(f"/map {i.width}x{i.height} res {i.resolution} vs map.yaml {w}x{h} {res} {origin}")
        else:
            # PGM row 0 is the top of the map; the grid's row 0 its bottom.
            wrong = sum(
                1 for r in range(h) for c in range(w)
                if trinary(g.data[r * w + c]) != pixels[(h - 1 - r) * w + c]
            )
            figures["map"] = {"width": w, "height": h, "cells_differing": wrong}
            if wrong:
                failures.append(f"/map: {wrong} cells differ from map.pgm")
    p = last.get("/trajectory")
    if p is not None:
        tum = read_tum(os.path.join(a.out, "trajectory.tum"))
        got = [(s.header.stamp.sec + s.header.stamp.nanosec * 1e-9, s.pose.position.x,
                s.pose.position.y, 2.0 * math.atan2(s.pose.orientation.z, s.pose.orientation.w))
               for s in p.poses]
        figures["trajectory_poses"] = len(got)
        if len(got) != len(tum):
            failures.append(f"/trajectory {len(got)} poses, trajectory.tum {len(tum)}")
        else:
            worst = max(max(abs(a_ - b_) for a_, b_ in zip(x[1:3], y[1:3])) for x, y in zip(got, tum))
            worst_t = max(abs(x[0] - y[0]) for x, y in zip(got, tum))
            figures["trajectory_max_difference_m"] = worst
            if worst > 1e-6 or worst_t > 1e-5:
                failures.append(f"/trajectory differs from trajectory.tum by {worst} m, {worst_t} s")


if __name__ == "__main__":
    main()
