#!/usr/bin/env python3
"""Reads an MCAP file written by `slam run --mcap` with independent readers and checks it.

Readers (none of them shares code with slam-rs):
* `mcap` (Foxglove's Python reader) for the container: header profile, chunk compression,
  channels, schemas;
* `mcap-ros2-support` decodes every message with the schema text the file carries;
* `rosbags` deserialises every message again with its *own* ROS 2 Humble definitions (not
  the file's), and its generated definition of each type is compared field by field with
  the file's schema, so a wrong field order or type would fail here even if the schema and
  the bytes agreed with each other.

Checks against the run's other outputs (written by other code of slam-rs, in --out):
* every topic given with --topics is present, and nothing else but the optional topics;
* the last /map has the width, height, resolution and origin of map.yaml + map.pgm, and
  every cell agrees with map.pgm's map_saver trinary value (occupied >= 65 black, free <= 25
  white, else grey);
* the last /trajectory has as many poses as trajectory.tum has records, with the same
  times (1 us) and positions (1e-6 m);
* every /tf message's map -> odom composed with odom -> base_link is the /pose estimate of
  the same stamp (1e-6 m, 1e-6 rad);
* every channel's offered_qos_profiles parses as YAML with the keys and integer policies
  rosbag2's QoS decoder reads (/tf_static and /map transient local).

    check_mcap.py RUN.mcap --out RUN_DIR --topics /pose,/tf,... [--laser]
Exit status 0 when every check passes; the summary is printed.
"""

import argparse
import math
import sys
from collections import Counter, defaultdict
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.typesys import Stores, get_typestore
from ruamel.yaml import YAML

TS = get_typestore(Stores.ROS2_HUMBLE)


def fail(msg):
    print(f'check_mcap: FAIL: {msg}')
    sys.exit(1)


def fields(text):
    """The (type, name) of the main message's fields, constants and default values dropped."""
    out = []
    for line in text.split('=' * 80)[0].splitlines():
        line = line.split('#')[0].strip()
        if not line or '=' in line:
            continue
        ty, name = line.split()[:2]
        out.append((ty, name))
    return out


def yaw(q):
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def compose(a, b):
    x, y, t = a
    c, s = math.cos(t), math.sin(t)
    return (x + c * b[0] - s * b[1], y + s * b[0] + c * b[1], t + b[2])


def wrap(a):
    return math.atan2(math.sin(a), math.cos(a))


def planar(tf):
    tr, q = tf.transform.translation, tf.transform.rotation
    return (tr.x, tr.y, yaw(q))


def read_yaml_map(out):
    meta = {}
    for line in (out / 'map.yaml').read_text().splitlines():
        k, _, v = line.partition(':')
        meta[k.strip()] = v.strip()
    ox, oy, _ = (float(v) for v in meta['origin'].strip('[]').split(','))
    data = (out / meta['image']).read_bytes()
    # Binary PGM: P5, width, height, maxval, then the pixels, first row the top of the map.
    parts, pos = [], 0
    while len(parts) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b'#':  # a comment, to the end of its line
            pos = data.index(b'\n', pos)
            continue
        end = pos
        while not data[end:end + 1].isspace():
            end += 1
        parts.append(data[pos:end])
        pos = end
    assert parts[0] == b'P5', parts[0]
    w, h = int(parts[1]), int(parts[2])
    pixels = data[pos + 1:pos + 1 + w * h]
    return float(meta['resolution']), (ox, oy), w, h, pixels


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('mcap', type=Path)
    ap.add_argument('--out', type=Path, required=True, help='the run folder (--out of slam run)')
    ap.add_argument('--topics', required=True, help='comma-separated topics that must be present')
    ap.add_argument('--optional', default='/ground_truth', help='topics that may be present')
    args = ap.parse_args()
    want = set(args.topics.split(','))
    optional = set(filter(None, args.optional.split(',')))

    with open(args.mcap, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        summary = reader.get_summary()
        if header.profile != 'ros2':
            fail(f'profile {header.profile!r}, expected ros2')
        compressions = {c.compression for c in summary.chunk_indexes}
        if not compressions <= {'zstd', 'lz4'}:
            fail(f'chunk compression {compressions}')
        for sc in summary.schemas.values():
            if sc.encoding != 'ros2msg':
                fail(f'schema {sc.name} encoding {sc.encoding}')
            ours = fields(sc.data.decode())
            theirs = fields(TS.generate_msgdef(sc.name, ros_version=2)[0])
            if ours != theirs:
                fail(f'{sc.name}: fields {ours} differ from rosbags\' Humble {theirs}')
        for ch in summary.channels.values():
            if ch.message_encoding != 'cdr':
                fail(f'{ch.topic}: message encoding {ch.message_encoding}')
            if 'offered_qos_profiles' not in ch.metadata:
                fail(f'{ch.topic}: no offered_qos_profiles')
            # The keys and integer policies rosbag2's QoS decoder reads (rosbag2_storage
            # qos.cpp: integer history means the metadata-version-8 form); /tf_static and /map
            # transient local (1), the rest volatile (2); reliable (1), keep last (1).
            (qos,) = YAML(typ='safe').load(ch.metadata['offered_qos_profiles'])
            keys = {'history', 'depth', 'reliability', 'durability', 'deadline', 'lifespan',
                    'liveliness', 'liveliness_lease_duration', 'avoid_ros_namespace_conventions'}
            latched = ch.topic in ('/tf_static', '/map')
            if set(qos) != keys or (qos['history'], qos['reliability'], qos['liveliness']) != (1, 1, 1) \
                    or qos['durability'] != (1 if latched else 2) \
                    or any(set(qos[d]) != {'sec', 'nsec'} for d in ('deadline', 'lifespan', 'liveliness_lease_duration')):
                fail(f'{ch.topic}: offered_qos_profiles {qos}')

        counts = Counter()
        last = {}
        poses = {}
        tfs = []
        for schema, channel, message, ros in reader.iter_decoded_messages():
            counts[channel.topic] += 1
            again = TS.deserialize_cdr(message.data, schema.name)
            if type(again).__name__ != schema.name.replace('/', '__'):
                fail(f'{channel.topic}: rosbags decoded a {type(again).__name__}')
            stamp = None
            if hasattr(ros, 'header'):
                stamp = ros.header.stamp.sec * 10**9 + ros.header.stamp.nanosec
                if stamp != message.log_time:
                    fail(f'{channel.topic}: header stamp {stamp} != log time {message.log_time}')
            if channel.topic == '/pose':
                p = ros.pose
                poses[stamp] = (p.position.x, p.position.y, yaw(p.orientation))
            if channel.topic == '/tf':
                tfs.append(ros.transforms)
            last[channel.topic] = (ros, again)

    got = set(counts)
    if not want <= got:
        fail(f'topics missing: {sorted(want - got)} (found {sorted(got)})')
    if not got <= want | optional:
        fail(f'unexpected topics: {sorted(got - want - optional)}')

    # /tf against /pose.
    for transforms in tfs:
        frames = [(t.header.frame_id, t.child_frame_id) for t in transforms]
        t = transforms[0].header.stamp
        stamp = t.sec * 10**9 + t.nanosec
        if frames == [('map', 'odom'), ('odom', 'base_link')]:
            base = compose(planar(transforms[0]), planar(transforms[1]))
        elif frames == [('map', 'base_link')]:
            base = planar(transforms[0])
        else:
            fail(f'/tf frames {frames}')
        p = poses[stamp]
        if abs(base[0] - p[0]) > 1e-6 or abs(base[1] - p[1]) > 1e-6 or abs(wrap(base[2] - p[2])) > 1e-6:
            fail(f'/tf at {stamp}: map -> base_link {base} but /pose {p}')

    # The last /trajectory against trajectory.tum.
    tum = [l.split() for l in (args.out / 'trajectory.tum').read_text().splitlines()
           if l.strip() and not l.startswith('#')]
    path = last['/trajectory'][0].poses
    if len(path) != len(tum):
        fail(f'/trajectory has {len(path)} poses, trajectory.tum {len(tum)} records')
    for ps, rec in zip(path, tum):
        t = ps.header.stamp.sec + ps.header.stamp.nanosec * 1e-9
        if abs(t - float(rec[0])) > 1e-6 or abs(ps.pose.position.x - float(rec[1])) > 1e-6 \
                or abs(ps.pose.position.y - float(rec[2])) > 1e-6:
            fail(f'/trajectory pose at {t} differs from trajectory.tum {rec[:3]}')

    line = f'check_mcap: {args.mcap}: {sum(counts.values())} messages on {len(counts)} topics ' \
           f'({", ".join(f"{k} {v}" for k, v in sorted(counts.items()))}), all decoded by ' \
           f'mcap-ros2 and rosbags; /trajectory {len(path)} poses = trajectory.tum; ' \
           f'{len(tfs)} /tf = /pose'

    # The last /map against map.yaml + map.pgm.
    if '/map' in counts:
        grid = last['/map'][0]
        info = grid.info
        res, (ox, oy), w, h, pixels = read_yaml_map(args.out)
        if (info.width, info.height) != (w, h):
            fail(f'/map {info.width} x {info.height}, map.pgm {w} x {h}')
        if abs(info.resolution - res) > 1e-6 * res:
            fail(f'/map resolution {info.resolution}, map.yaml {res}')
        o = info.origin
        if abs(o.position.x - ox) > 1e-9 or abs(o.position.y - oy) > 1e-9 or abs(yaw(o.orientation)) > 1e-12:
            fail(f'/map origin ({o.position.x}, {o.position.y}), map.yaml ({ox}, {oy})')
        if grid.header.frame_id != 'map' or len(grid.data) != w * h:
            fail('/map frame or data length')
        bad = 0
        for iy in range(h):
            row = pixels[(h - 1 - iy) * w:(h - iy) * w]
            for ix in range(w):
                v = int(grid.data[iy * w + ix])
                if not -1 <= v <= 100:
                    fail(f'/map cell ({ix}, {iy}) = {v}')
                expect = 0 if v >= 65 else 254 if 0 <= v <= 25 else 205
                bad += row[ix] != expect
        if bad:
            fail(f'/map: {bad} cells disagree with map.pgm')
        line += f'; /map {w} x {h} at {res} m, origin ({ox}, {oy}) = map.yaml, cells = map.pgm'
    if '/landmarks' in counts:
        markers = last['/landmarks'][0].markers
        ellipses = [m for m in markers if m.ns == 'ellipses']
        csv = [l for l in (args.out / 'landmarks.csv').read_text().splitlines()[1:] if l.strip()]
        if markers[0].action != 3 or len(ellipses) != len(csv):
            fail(f'/landmarks: {len(ellipses)} ellipses, landmarks.csv {len(csv)} rows')
        # Each ellipse's axis end points lie on the 95 % contour of landmarks.csv's
        # covariance: d^T S^-1 d = chi2_2(0.95) = 5.991.
        rows = {int(r.split(',')[0]): [float(v) for v in r.split(',')[1:]] for r in csv}
        for m in ellipses:
            x, y, cxx, cxy, cyy = rows[m.id]
            if abs(m.pose.position.x - x) > 1e-9 or abs(m.pose.position.y - y) > 1e-9:
                fail(f'/landmarks: ellipse {m.id} not at landmarks.csv\'s mean')
            det = cxx * cyy - cxy * cxy
            a = yaw(m.pose.orientation)
            for half, ang in ((m.scale.x / 2, a), (m.scale.y / 2, a + math.pi / 2)):
                dx, dy = half * math.cos(ang), half * math.sin(ang)
                d2 = (cyy * dx * dx - 2 * cxy * dx * dy + cxx * dy * dy) / det
                if half > 1e-3 and abs(d2 - 5.991) > 0.01:
                    fail(f'/landmarks: ellipse {m.id} axis at Mahalanobis^2 {d2}, not 5.991')
        line += f'; /landmarks {len(ellipses)} ellipses = landmarks.csv rows, on its 95 % contours'
    print(line)


if __name__ == '__main__':
    main()
