//! `cargo xtask eval hostile`: the hostile-input cases of issue 32 too large for the test
//! suite's time budget. ROS 1 bags of 2.5 GiB and 5 GiB are generated (sparse files: the
//! large message bodies are holes, so they take no disk space and seconds to write), then
//! `slam info` and `slam run --filter scanmatch` read them under `/usr/bin/time -v`. The
//! verdict: both succeed, with the counts the generator wrote, and each process's peak RSS
//! stays below [`RSS_BOUND_MIB`] (the readers stream the file record by record; before
//! issue 32 they read the whole file into memory and failed).
//!
//! Each bag (format 2.0, unindexed, as a recording cut short before its index) holds
//! [`SCANS`] `sensor_msgs/LaserScan` messages on `/scan` (180 beams, every one 2 m: the
//! robot in a circular room), half at the start and half at the end of the file, and
//! between them `std_msgs/String` messages on `/blob` of [`BLOB_BYTES`] each, as many as
//! reach the size. Written from the format's specification (wiki.ros.org/Bags/Format/2.0).

use std::io::{Seek, SeekFrom, Write};
use std::path::Path;
use std::process::Command;

/// Scans per bag.
const SCANS: u32 = 20;
/// Bytes of each `/blob` message's data (64 MiB, a quarter of slam-io's record cap).
const BLOB_BYTES: u64 = 64 << 20;
/// The largest peak RSS accepted, MiB.
const RSS_BOUND_MIB: u64 = 512;

// slam-io's ROS 1 record writer, compiled from its one source rather than linked (xtask
// does not depend on the workspace's crates).
#[allow(dead_code)] // `ros1_record`: the bags here stream their data after the head.
#[path = "../../crates/slam-io/src/rosbag/ros1_record.rs"]
mod record;
use record::ros1_record_head as record_head;

/// A connection record: `id`, `topic`, type and md5sum.
fn connection(id: u32, topic: &str, ty: &str, md5: &str) -> Vec<u8> {
    let mut data = Vec::new();
    for (n, v) in [("type", ty), ("md5sum", md5), ("message_definition", "")] {
        data.extend((n.len() as u32 + 1 + v.len() as u32).to_le_bytes());
        data.extend(n.as_bytes());
        data.push(b'=');
        data.extend(v.as_bytes());
    }
    let mut r = record_head(
        &[
            ("op", &[0x07]),
            ("conn", &id.to_le_bytes()),
            ("topic", topic.as_bytes()),
        ],
        data.len() as u32,
    );
    r.extend(data);
    r
}

/// A message record's head on connection `conn` at `sec` s, for `len` bytes of data.
fn message_head(conn: u32, sec: u32, len: u32) -> Vec<u8> {
    let mut t = sec.to_le_bytes().to_vec();
    t.extend(0u32.to_le_bytes());
    record_head(
        &[("op", &[0x02]), ("conn", &conn.to_le_bytes()), ("time", &t)],
        len,
    )
}

/// A ROS 1 `sensor_msgs/LaserScan` body at `sec` s: 180 beams over 179°, all 2 m.
fn scan_body(sec: u32) -> Vec<u8> {
    let mut b = Vec::new();
    b.extend(0u32.to_le_bytes()); // seq
    b.extend(sec.to_le_bytes());
    b.extend(0u32.to_le_bytes());
    b.extend(5u32.to_le_bytes());
    b.extend(b"laser");
    let inc = std::f32::consts::PI / 180.0;
    let min = -std::f32::consts::FRAC_PI_2;
    for v in [min, min + 179.0 * inc, inc, 0.0, 0.0, 0.0, 30.0] {
        b.extend(v.to_le_bytes());
    }
    b.extend(180u32.to_le_bytes());
    for _ in 0..180 {
        b.extend(2.0f32.to_le_bytes());
    }
    b.extend(0u32.to_le_bytes()); // no intensities
    b
}

/// Writes the bag of about `size` bytes at `path`; returns the number of `/blob` messages.
fn write_bag(path: &Path, size: u64) -> Result<u64, String> {
    let err = |e: std::io::Error| format!("{}: {e}", path.display());
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).map_err(err)?);
    f.write_all(b"#ROSBAG V2.0\n").map_err(err)?;
    f.write_all(&record_head(
        &[
            ("op", &[0x03]),
            ("index_pos", &0u64.to_le_bytes()),
            ("conn_count", &2u32.to_le_bytes()),
            ("chunk_count", &0u32.to_le_bytes()),
        ],
        0,
    ))
    .map_err(err)?;
    f.write_all(&connection(
        0,
        "/scan",
        "sensor_msgs/LaserScan",
        "90c7ef2dc6895d81024acba2ac42f369",
    ))
    .map_err(err)?;
    f.write_all(&connection(
        1,
        "/blob",
        "std_msgs/String",
        "992ce8a1687cec8c8bd883ec73ca41d1",
    ))
    .map_err(err)?;
    let scan = |f: &mut std::io::BufWriter<std::fs::File>, sec: u32| {
        let body = scan_body(sec);
        f.write_all(&message_head(0, sec, body.len() as u32))?;
        f.write_all(&body)
    };
    let mut sec = 1000;
    for _ in 0..SCANS / 2 {
        scan(&mut f, sec).map_err(err)?;
        sec += 1;
    }
    let mut blobs = 0;
    while f.stream_position().map_err(err)? + BLOB_BYTES < size {
        // std_msgs/String: a uint32 length, then the bytes (here a hole of zeros).
        f.write_all(&message_head(1, sec, BLOB_BYTES as u32))
            .map_err(err)?;
        f.write_all(&((BLOB_BYTES - 4) as u32).to_le_bytes())
            .map_err(err)?;
        f.seek(SeekFrom::Current(BLOB_BYTES as i64 - 4))
            .map_err(err)?;
        blobs += 1;
    }
    for _ in 0..SCANS / 2 {
        sec += 1;
        scan(&mut f, sec).map_err(err)?;
    }
    f.flush().map_err(err)?;
    Ok(blobs)
}

/// The peak RSS (KiB) that `/usr/bin/time -v` printed in `stderr`.
fn peak_rss_kib(stderr: &str) -> Result<u64, String> {
    stderr
        .lines()
        .find_map(|l| {
            l.trim()
                .strip_prefix("Maximum resident set size (kbytes): ")
        })
        .and_then(|v| v.trim().parse::<u64>().ok())
        .ok_or_else(|| format!("no peak RSS in /usr/bin/time's output:\n{stderr}"))
}

/// Runs `slam args` under `/usr/bin/time -v`: its stdout and its peak RSS in MiB.
fn timed(exe: &Path, args: &[&str]) -> Result<(String, u64), String> {
    let o = Command::new("/usr/bin/time")
        .arg("-v")
        .arg(exe)
        .args(args)
        .output()
        .map_err(|e| format!("/usr/bin/time: {e}"))?;
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    if !o.status.success() {
        return Err(format!("slam {}: {err}", args.join(" ")));
    }
    let kib = peak_rss_kib(&err)?;
    Ok((String::from_utf8_lossy(&o.stdout).into_owned(), kib / 1024))
}

/// The ignored gzip tests of slam-io's `tests/hostile.rs`, each run alone under
/// `/usr/bin/time -v`, with the bound on its peak RSS in MiB: the gzip of zeros is refused at
/// its first block (test harness and one block: 256 MiB), the gzip of empty lines at the
/// 2 GiB text cap (the cap and 256 MiB for the rest).
const GZIP_TESTS: [(&str, &str, u64); 2] = [
    (
        "a_gzip_of_zeros_beyond_the_cap_is_refused_at_its_first_block",
        "gzip of 2 GiB + 1 MiB zeros refused at its first block",
        256,
    ),
    (
        "a_gzip_of_empty_lines_beyond_the_cap_is_refused_by_the_cap",
        "gzip of 2 GiB + 1 MiB empty lines refused by the 2 GiB text cap",
        2048 + 256,
    ),
];

/// The cargo arguments of slam-io's hostile tests.
const HOSTILE_TESTS: [&str; 6] = ["test", "--release", "-p", "slam-io", "--test", "hostile"];

/// `cargo test -p slam-io --test hostile -- --ignored --exact NAME` under `/usr/bin/time -v`
/// for each of [`GZIP_TESTS`].
fn run_ignored_gzip_tests() -> Result<(), String> {
    super::run(
        "build slam-io's hostile tests",
        super::cargo().args(HOSTILE_TESTS).arg("--no-run"),
    )?;
    for (name, what, bound_mib) in GZIP_TESTS {
        let o = Command::new("/usr/bin/time")
            .arg("-v")
            .arg(super::cargo_path())
            .args(HOSTILE_TESTS)
            .args(["--", "--ignored", "--exact", name])
            .output()
            .map_err(|e| format!("/usr/bin/time: {e}"))?;
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        let out = String::from_utf8_lossy(&o.stdout);
        if !o.status.success() || !out.contains("1 passed") {
            return Err(format!(
                "the ignored hostile test {name} failed:\n{out}{err}"
            ));
        }
        let kib = peak_rss_kib(&err)?;
        println!("hostile: {what}; peak RSS {} MiB", kib / 1024);
        if kib / 1024 > bound_mib {
            return Err(format!("{what}: peak RSS {} MiB > {bound_mib}", kib / 1024));
        }
    }
    Ok(())
}

/// The step (module doc).
pub fn hostile() -> Result<(), String> {
    let exe = super::build_slam()?;
    // The gzips beyond the text cap (slam-io's ignored hostile tests), each with its bound.
    run_ignored_gzip_tests()?;
    let dir = std::env::temp_dir().join(format!("slam-hostile-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut failures = Vec::new();
    for (name, size) in [("2.5 GiB", 5u64 << 29), ("5 GiB", 5u64 << 30)] {
        let bag = dir.join("large.bag");
        let blobs = write_bag(&bag, size)?;
        let len = std::fs::metadata(&bag).map_err(|e| e.to_string())?.len();
        let bag_s = bag.to_str().ok_or("temp path is not UTF-8")?;
        let (info, info_rss) = timed(&exe, &["info", bag_s])?;
        let out = dir.join("out");
        let out_s = out.to_str().ok_or("temp path is not UTF-8")?;
        let (_, run_rss) = timed(
            &exe,
            &[
                "run",
                "--filter",
                "scanmatch",
                "--dataset",
                bag_s,
                "--quiet",
                "--out",
                out_s,
            ],
        )?;
        let poses = std::fs::read_to_string(out.join("trajectory.tum"))
            .map_err(|e| format!("{}: {e}", out.display()))?
            .lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
            .count();
        let counts_ok = info.contains(&format!("{} message(s)", blobs + u64::from(SCANS)))
            && poses == SCANS as usize;
        println!(
            "hostile: {name} bag ({len} bytes, {blobs} /blob messages of {BLOB_BYTES} bytes, \
             {SCANS} scans): slam info peak RSS {info_rss} MiB, slam run {run_rss} MiB, \
             {poses} poses; counts {}",
            if counts_ok { "right" } else { "WRONG" }
        );
        if !counts_ok {
            failures.push(format!("{name}: wrong counts\n{info}"));
        }
        for (what, rss) in [("info", info_rss), ("run", run_rss)] {
            if rss > RSS_BOUND_MIB {
                failures.push(format!(
                    "{name}: slam {what} peak RSS {rss} MiB > {RSS_BOUND_MIB}"
                ));
            }
        }
        let _ = std::fs::remove_file(&bag);
        let _ = std::fs::remove_dir_all(&out);
    }
    let _ = std::fs::remove_dir_all(&dir);
    if failures.is_empty() {
        Ok(())
    } else {
        Err(failures.join("\n"))
    }
}
