//! Hostile input through every reader (issue 17): malformed variants generated at test time
//! from the real datasets in `../shared/datasets`, a property-based fuzz of every reader,
//! and a regression test for each reader defect the issue lists.
//!
//! Every variant runs under `catch_unwind`: a panic fails the test. Each variant states what
//! must happen: an error naming the file and the line that was corrupted; an error naming the
//! file; the same data as the unmodified file (BOM, CRLF, gzip, multi-member gzip); or, for a
//! truncation, an error or a prefix of the original. A corrupted value (NaN, ∞, 1e308, an
//! out-of-bounds number, a garbled field) must always be an error: nothing is silently
//! accepted.

mod common;

use proptest::prelude::*;
use slam::io::{carmen, freiburg, landmarks_csv, mrclam, relations, ros_map, tum, IoError};
use slam::models::{GridMap, LandmarkEstimate, LandmarkId, Matrix2, Point2};
use std::io::Write as _;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

/// A scratch folder, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(tag: &str) -> Self {
        let p =
            std::env::temp_dir().join(format!("slam-io-malformed-{tag}-{}", std::process::id()));
        std::fs::remove_dir_all(&p).ok();
        std::fs::create_dir_all(&p).unwrap();
        Scratch(p)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        std::fs::remove_dir_all(&self.0).ok();
    }
}

/// Runs `f`, failing the test (with `what`) if it panics.
fn no_panic<T>(what: &str, f: impl FnOnce() -> T) -> T {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(v) => v,
        Err(p) => {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            panic!("{what}: the reader panicked: {msg}")
        }
    }
}

/// What a reader gives back, reduced to what the checks compare: the number of items read
/// and a fingerprint of all of them (their `Debug` text).
type Outcome = Result<(usize, String), IoError>;

/// What a variant must give.
#[derive(Debug, Clone, PartialEq)]
enum Expect {
    /// An error naming the mutated file and this 1-based line.
    ErrAt(usize),
    /// An error naming the mutated file.
    Err,
    /// An error naming this file (another file than the mutated one).
    ErrNaming(&'static str),
    /// The same data as the unmodified file.
    Same,
    /// An error naming the file, or a result with no more items than the original.
    Prefix,
    /// No panic; an error must name the file.
    Any,
}

struct Variant {
    name: String,
    bytes: Vec<u8>,
    expect: Expect,
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

/// The 1-based numbers of the lines a reader parses field by field (not blank, not a
/// comment, not a CARMEN PARAM line whose value is free text).
fn data_line_numbers(text: &str) -> Vec<usize> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| {
            let t = l.trim();
            !t.is_empty() && !t.starts_with('#') && !t.starts_with("PARAM") && !t.starts_with("id,")
        })
        .map(|(i, _)| i + 1)
        .collect()
}

/// Rewrites line `no` (1-based) with `f` applied to its whitespace-separated fields (for
/// CSV, comma-separated).
fn edit_line(text: &str, no: usize, f: impl Fn(&mut Vec<String>)) -> String {
    let csv = text.starts_with("id,");
    let mut out = String::with_capacity(text.len() + 64);
    for (i, l) in text.lines().enumerate() {
        if i + 1 == no {
            let mut fields: Vec<String> = if csv {
                l.split(',').map(str::to_string).collect()
            } else {
                l.split_whitespace().map(str::to_string).collect()
            };
            f(&mut fields);
            out.push_str(&fields.join(if csv { "," } else { " " }));
        } else {
            out.push_str(l);
        }
        out.push('\n');
    }
    out
}

/// Indices of the fields of line `no` that are numbers.
fn numeric_fields(text: &str, no: usize) -> Vec<usize> {
    let l = text.lines().nth(no - 1).unwrap_or("");
    let fields: Vec<&str> = if text.starts_with("id,") {
        l.split(',').collect()
    } else {
        l.split_whitespace().collect()
    };
    (0..fields.len())
        .filter(|&k| fields[k].parse::<f64>().is_ok())
        .collect()
}

/// The malformed variants of a line-oriented text file (at least 20 kinds). `seed` picks
/// the lines and fields deterministically.
fn line_file_variants(text: &str, seed: u64) -> Vec<Variant> {
    let lines = data_line_numbers(text);
    assert!(lines.len() >= 3, "base file too small");
    let pick = |k: u64| {
        lines[((seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(k * 1442695040888963407))
            >> 33) as usize
            % lines.len()]
    };
    let field_of = |no: usize, k: u64| {
        let f = numeric_fields(text, no);
        assert!(!f.is_empty(), "line {no} has no number");
        f[(seed as usize + k as usize) % f.len()]
    };
    let mut v = Vec::new();
    let mut add = |name: &str, bytes: Vec<u8>, expect: Expect| {
        v.push(Variant {
            name: name.to_string(),
            bytes,
            expect,
        })
    };
    add("empty file", Vec::new(), Expect::Err);
    add(
        "comments only",
        b"# nothing here\n\n   \n".to_vec(),
        Expect::Err,
    );
    add(
        "truncated mid-file",
        text.as_bytes()[..text.len() / 2].to_vec(),
        Expect::Prefix,
    );
    let half: String = text
        .lines()
        .take(text.lines().count() / 2)
        .map(|l| format!("{l}\n"))
        .collect();
    add("truncated at a line end", half.into_bytes(), Expect::Prefix);
    let mut rng = seed | 1;
    let garbage: Vec<u8> = (0..4096)
        .map(|_| {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 24) as u8
        })
        .collect();
    add("binary garbage", garbage, Expect::Err);
    let no = pick(1);
    let mut bad_utf8 = Vec::new();
    for (i, l) in text.lines().enumerate() {
        bad_utf8.extend_from_slice(l.as_bytes());
        if i + 1 == no {
            bad_utf8.extend_from_slice(&[b' ', 0xff, 0xfe]);
        }
        bad_utf8.push(b'\n');
    }
    add("invalid UTF-8", bad_utf8, Expect::ErrAt(no));
    for (k, (name, value)) in [
        ("garbled number", "1.2.3"),
        ("NaN", "NaN"),
        ("inf", "inf"),
        ("-inf", "-inf"),
        ("1e308", "1e308"),
        ("-1e308", "-1e308"),
        ("1e13", "1e13"),
        ("NUL byte", "1\0"),
        ("a megabyte of digits", &"9".repeat(1 << 20)),
    ]
    .into_iter()
    .enumerate()
    {
        let no = pick(10 + k as u64);
        let field = field_of(no, k as u64);
        let t = edit_line(text, no, |f| f[field] = value.to_string());
        add(
            &format!("{name} in field {field}"),
            t.into_bytes(),
            Expect::ErrAt(no),
        );
    }
    let no = pick(30);
    // A line of one field becomes blank (skipped): then only the file can be named.
    let one_field = text.lines().nth(no - 1).unwrap().split_whitespace().count() == 1;
    add(
        "missing last field",
        edit_line(text, no, |f| {
            f.pop();
        })
        .into_bytes(),
        if one_field {
            Expect::Err
        } else {
            Expect::ErrAt(no)
        },
    );
    let no = pick(31);
    add(
        "extra field",
        edit_line(text, no, |f| f.push("7".into())).into_bytes(),
        Expect::ErrAt(no),
    );
    // 1e308 in every numeric field of the first line of each record type (for lines of many
    // fields: the first 10 and the last 20, where poses, speeds and stamps are).
    let mut kinds_seen = Vec::new();
    for &no in &lines {
        let l = text.lines().nth(no - 1).unwrap();
        let kind = l
            .split(|c: char| c.is_whitespace() || c == ',')
            .next()
            .unwrap_or("");
        let kind = if kind.parse::<f64>().is_ok() {
            ""
        } else {
            kind
        };
        if kinds_seen.contains(&kind) {
            continue;
        }
        kinds_seen.push(kind);
        let fields = numeric_fields(text, no);
        let n = fields.len();
        for (j, &field) in fields.iter().enumerate() {
            if j >= 10 && j + 20 < n {
                continue;
            }
            let t = edit_line(text, no, |f| f[field] = "1e308".into());
            add(
                &format!("1e308 in field {field} of line {no}"),
                t.into_bytes(),
                Expect::ErrAt(no),
            );
        }
    }
    let mut bom = vec![0xef, 0xbb, 0xbf];
    bom.extend_from_slice(text.as_bytes());
    add("byte-order mark", bom.clone(), Expect::Same);
    let crlf = text.replace('\n', "\r\n");
    add("CRLF line ends", crlf.clone().into_bytes(), Expect::Same);
    let mut bom_crlf = vec![0xef, 0xbb, 0xbf];
    bom_crlf.extend_from_slice(crlf.as_bytes());
    add("gzip of BOM + CRLF", gzip(&bom_crlf), Expect::Same);
    let split = half_at_line(text);
    add(
        "two gzip members",
        [
            gzip(&text.as_bytes()[..split]),
            gzip(&text.as_bytes()[split..]),
        ]
        .concat(),
        Expect::Same,
    );
    let z = gzip(text.as_bytes());
    add("truncated gzip", z[..z.len() * 2 / 3].to_vec(), Expect::Err);
    add(
        "gzip then garbage",
        [z.clone(), b"trailing garbage".to_vec()].concat(),
        Expect::Err,
    );
    let no = pick(40);
    let dup: String = text
        .lines()
        .enumerate()
        .flat_map(|(i, l)| {
            let n = if i + 1 == no { 2 } else { 1 };
            std::iter::repeat_n(format!("{l}\n"), n)
        })
        .collect();
    add("duplicated line", dup.into_bytes(), Expect::Any);
    v
}

/// A byte offset just after a line end near the middle of `text`.
fn half_at_line(text: &str) -> usize {
    text[..text.len() / 2].rfind('\n').map_or(0, |i| i + 1)
}

/// Checks one outcome against its expectation; `file` is the mutated file's name.
fn check(reader: &str, v: &Variant, file: &str, base: &(usize, String), got: Outcome) {
    let what = format!("{reader}, {}", v.name);
    match (&v.expect, got) {
        (Expect::ErrAt(no), Err(e)) => {
            let s = e.to_string();
            assert!(
                s.contains(&format!("{file}:{no}:")),
                "{what}: error does not name {file}:{no}: {s}"
            );
        }
        (Expect::Err | Expect::Prefix | Expect::Any, Err(e)) => {
            let s = e.to_string();
            assert!(s.contains(file), "{what}: error does not name {file}: {s}");
        }
        (Expect::ErrNaming(other), Err(e)) => {
            let s = e.to_string();
            assert!(
                s.contains(other),
                "{what}: error does not name {other}: {s}"
            );
        }
        (Expect::Same, Ok(r)) => assert!(r == *base, "{what}: data differs from the original"),
        (Expect::Prefix, Ok((n, _))) => {
            assert!(
                n <= base.0,
                "{what}: {n} items from a truncated file, {} in the whole",
                base.0
            )
        }
        (Expect::Any, Ok(_)) => {}
        (want, Ok(_)) => panic!("{what}: accepted, expected {want:?}"),
        (want, Err(e)) => panic!("{what}: {e}, expected {want:?}"),
    }
}

/// Runs every variant of `base` (the content of `file`) through `read`, which reads the
/// dataset from a folder where `file` holds the variant (`setup` links the other files).
fn run_variants(
    reader: &str,
    file: &str,
    base_text: &str,
    setup: impl Fn(&Path),
    read: impl Fn(&Path) -> Outcome,
    extra: Vec<Variant>,
    optional: bool,
) {
    let dir = Scratch::new(&format!("{reader}-{}", file.replace('.', "_")));
    setup(&dir.0);
    let target = dir.0.join(file);
    std::fs::write(&target, base_text).unwrap();
    let base = no_panic(reader, || read(&dir.0))
        .unwrap_or_else(|e| panic!("{reader}: base file refused: {e}"));
    let mut variants = line_file_variants(base_text, reader.len() as u64 * 7919);
    variants.extend(extra);
    assert!(
        variants.len() >= 20,
        "{reader}: only {} variants",
        variants.len()
    );
    for v in &variants {
        std::fs::write(&target, &v.bytes).unwrap();
        let got = no_panic(&format!("{reader}, {}", v.name), || read(&dir.0));
        check(reader, v, file, &base, got);
    }
    // A folder where the file should be, and no file at all.
    std::fs::remove_file(&target).unwrap();
    for what in ["missing file", "a folder instead of the file"] {
        if what.starts_with('a') {
            std::fs::create_dir(&target).unwrap();
        }
        let got = no_panic(&format!("{reader}, {what}"), || read(&dir.0));
        match got {
            // An optional file that is absent (or not a file) is not read.
            Ok(_) if optional => {}
            Ok(_) => panic!("{reader}, {what}: accepted"),
            Err(e) => {
                let e = e.to_string();
                assert!(
                    e.contains(file) || e.contains(&*dir.0.to_string_lossy()),
                    "{reader}, {what}: {e}"
                );
            }
        }
    }
}

fn link(src_dir: &Path, dst: &Path, names: &[&str]) {
    for n in names {
        std::os::unix::fs::symlink(src_dir.join(n), dst.join(n)).unwrap();
    }
}

fn first_lines(path: &Path, n: usize) -> String {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .take(n)
        .map(|l| format!("{l}\n"))
        .collect()
}

fn extra(name: &str, text: String, expect: Expect) -> Variant {
    Variant {
        name: name.into(),
        bytes: text.into_bytes(),
        expect,
    }
}

/// The first line of `text` (1-based) that starts with `prefix`.
fn line_starting(text: &str, prefix: &str) -> usize {
    text.lines().position(|l| l.starts_with(prefix)).unwrap() + 1
}

fn carmen_outcome(p: &Path) -> Outcome {
    carmen::read_carmen(p).map(|l| (l.dataset.records.len(), format!("{:?}", l.dataset)))
}

#[test]
fn carmen_malformed_variants() {
    let Some(log) = common::dataset("bench/intel.log") else {
        return;
    };
    let text = first_lines(&log, 400);
    let fl = line_starting(&text, "FLASER");
    let od = line_starting(&text, "ODOM");
    let extras = vec![
        // Huge counts: N far beyond the cap, and a cap-sized N with few readings.
        extra("N = 10^12", edit_line(&text, fl, |f| f[1] = "1000000000000".into()), Expect::ErrAt(fl)),
        extra("N = 99999", edit_line(&text, fl, |f| f[1] = "99999".into()), Expect::ErrAt(fl)),
        extra("negative range", edit_line(&text, fl, |f| f[5] = "-0.5".into()), Expect::ErrAt(fl)),
        extra("range 5000 m", edit_line(&text, fl, |f| f[5] = "5000".into()), Expect::ErrAt(fl)),
        extra("odometry x 2e6 m", edit_line(&text, od, |f| f[1] = "2e6".into()), Expect::ErrAt(od)),
        extra("heading 1e5 rad", edit_line(&text, od, |f| f[3] = "1e5".into()), Expect::ErrAt(od)),
        extra("tv 1e4 m/s", edit_line(&text, od, |f| f[4] = "1e4".into()), Expect::ErrAt(od)),
        extra("time 1e11 s", edit_line(&text, od, |f| f[7] = "1e11".into()), Expect::ErrAt(od)),
        // Times stepping back or repeating are kept in file order (checked below too).
        extra("time far back", edit_line(&text, od, |f| f[7] = "1000".into()), Expect::Any),
        extra("unknown record type", text.clone() + "FOO 1 2 3\n", Expect::Any),
        extra(
            "ROBOTLASER1 fov 1e-300",
            text.clone() + "ROBOTLASER1 0 -1.5 1e-300 0.01 80 0.01 0 3 1 2 3 0 0 0 0 0 0 0 0 0 0 0 0 5 h 5\n",
            Expect::ErrAt(text.lines().count() + 1),
        ),
        extra(
            "ROBOTLASER1 angular_res 0",
            text.clone() + "ROBOTLASER1 0 -1.5 0.02 0 80 0.01 0 3 1 2 3 0 0 0 0 0 0 0 0 0 0 0 0 5 h 5\n",
            Expect::ErrAt(text.lines().count() + 1),
        ),
        extra(
            "ROBOTLASER1 start angle 100",
            text.clone() + "ROBOTLASER1 0 100 0.02 0.01 80 0.01 0 3 1 2 3 0 0 0 0 0 0 0 0 0 0 0 0 5 h 5\n",
            Expect::ErrAt(text.lines().count() + 1),
        ),
        extra(
            "RAWLASER2 max_range 1e308",
            text.clone() + "RAWLASER2 0 -1.5 0.02 0.01 1e308 0.01 0 3 1 2 3 0 5 h 5\n",
            Expect::ErrAt(text.lines().count() + 1),
        ),
        extra(
            "laser offset PARAM 1e308",
            format!("PARAM robot_frontlaser_offset 1e308\n{text}"),
            Expect::ErrAt(1),
        ),
    ];
    run_variants(
        "carmen",
        "intel.log",
        &text,
        |_| {},
        |d| carmen_outcome(&d.join("intel.log")),
        extras,
        false,
    );

    // A record stamped far back is kept where it is, with the time it was given.
    let dir = Scratch::new("carmen-back");
    let p = dir.0.join("back.log");
    std::fs::write(&p, edit_line(&text, od, |f| f[7] = "1000".into())).unwrap();
    let log = carmen::read_carmen(&p).unwrap();
    let base = carmen::read_carmen(&log_with(&dir.0, &text)).unwrap();
    let k = text
        .lines()
        .take(od)
        .filter(|l| l.starts_with("ODOM") || l.starts_with("FLASER"))
        .count()
        - 1;
    assert_eq!(log.dataset.records[k].t, 1000.0);
    assert_eq!(log.dataset.records.len(), base.dataset.records.len());
}

fn log_with(dir: &Path, text: &str) -> PathBuf {
    let p = dir.join("base.log");
    std::fs::write(&p, text).unwrap();
    p
}

fn freiburg_outcome(d: &Path) -> Outcome {
    freiburg::read_freiburg_report(d).map(|r| {
        let obs: usize = r.dataset.steps.iter().map(|s| s.observations.len()).sum();
        (
            r.dataset.steps.len() + obs + r.dataset.landmarks.as_ref().map_or(0, |l| l.len()),
            format!("{:?} {:?}", r.dataset.steps, r.dataset.landmarks),
        )
    })
}

#[test]
fn freiburg_malformed_variants() {
    let Some(dir) = common::dataset("freiburg-robot-mapping") else {
        return;
    };
    let sensor = std::fs::read_to_string(dir.join("sensor_data.dat")).unwrap();
    let world = std::fs::read_to_string(dir.join("world.dat")).unwrap();
    let od = line_starting(&sensor, "ODOMETRY");
    let se = line_starting(&sensor, "SENSOR");
    let extras = vec![
        extra(
            "r1 = 10 rad",
            edit_line(&sensor, od, |f| f[1] = "10".into()),
            Expect::ErrAt(od),
        ),
        extra(
            "t = 2e6 m",
            edit_line(&sensor, od, |f| f[2] = "2e6".into()),
            Expect::ErrAt(od),
        ),
        extra(
            "range 5000 m",
            edit_line(&sensor, se, |f| f[2] = "5000".into()),
            Expect::ErrAt(se),
        ),
        extra(
            "bearing 1e9",
            edit_line(&sensor, se, |f| f[3] = "1e9".into()),
            Expect::ErrAt(se),
        ),
        extra(
            "id 2^40",
            edit_line(&sensor, se, |f| f[1] = "1099511627776".into()),
            Expect::ErrAt(se),
        ),
        extra(
            "SENSOR first",
            format!("SENSOR 1 1 0\n{sensor}"),
            Expect::ErrAt(1),
        ),
    ];
    run_variants(
        "freiburg",
        "sensor_data.dat",
        &sensor,
        |d| link(&dir, d, &["world.dat"]),
        freiburg_outcome,
        extras,
        false,
    );
    let extras = vec![
        extra(
            "duplicate id",
            format!("{world}1 5 5\n"),
            Expect::ErrAt(world.lines().count() + 1),
        ),
        extra(
            "x = 2e6 m",
            edit_line(&world, 1, |f| f[1] = "2e6".into()),
            Expect::ErrAt(1),
        ),
    ];
    run_variants(
        "freiburg",
        "world.dat",
        &world,
        |d| link(&dir, d, &["sensor_data.dat"]),
        freiburg_outcome,
        extras,
        true,
    );
    // Sidecar times: a step time far from the others is refused.
    let times: String = (0..331)
        .map(|k| format!("{}\n", 100.0 + k as f64 * 0.1))
        .collect();
    let extras = vec![extra(
        "time 2e7 s later",
        edit_line(&times, 5, |f| f[0] = "2e7".into()),
        Expect::ErrAt(5),
    )];
    run_variants(
        "freiburg",
        "times.dat",
        &times,
        |d| link(&dir, d, &["sensor_data.dat", "world.dat"]),
        freiburg_outcome,
        extras,
        true,
    );
}

fn mrclam_outcome(d: &Path) -> Outcome {
    mrclam::read_mrclam_report(d, 1).map(|r| {
        let obs: usize = r.dataset.steps.iter().map(|s| s.observations.len()).sum();
        (
            r.dataset.steps.len() + obs + r.skipped.len(),
            format!("{:?} {:?}", r.dataset, r.skipped),
        )
    })
}

#[test]
fn mrclam_malformed_variants() {
    let Some(dir) = common::dataset("utias-mrclam/MRCLAM_Dataset1") else {
        return;
    };
    let files = [
        ("Robot1_Odometry.dat", 1500),
        ("Robot1_Measurement.dat", 120),
        ("Landmark_Groundtruth.dat", 100),
        ("Barcodes.dat", 100),
    ];
    let texts: Vec<String> = files
        .iter()
        .map(|(f, n)| first_lines(&dir.join(f), *n))
        .collect();
    for (i, (file, _)) in files.iter().enumerate() {
        let text = &texts[i];
        let first = data_line_numbers(text)[0];
        let second = data_line_numbers(text)[1];
        let extras = match *file {
            "Robot1_Odometry.dat" => vec![
                extra(
                    "time backwards",
                    edit_line(text, second, |f| f[0] = "1248272000".into()),
                    Expect::ErrAt(second),
                ),
                extra(
                    "v = 1e4 m/s",
                    edit_line(text, first, |f| f[1] = "1e4".into()),
                    Expect::ErrAt(first),
                ),
                extra(
                    "time 1e11 s",
                    edit_line(text, first, |f| f[0] = "1e11".into()),
                    Expect::ErrAt(first),
                ),
            ],
            "Robot1_Measurement.dat" => vec![
                extra(
                    "range 5000 m",
                    edit_line(text, first, |f| f[2] = "5000".into()),
                    Expect::ErrAt(first),
                ),
                extra(
                    "time a year off",
                    edit_line(text, first, |f| f[0] = "1280000000".into()),
                    Expect::ErrAt(first),
                ),
            ],
            "Landmark_Groundtruth.dat" => vec![extra(
                "x = 2e6 m",
                edit_line(text, first, |f| f[1] = "2e6".into()),
                Expect::ErrAt(first),
            )],
            _ => vec![extra(
                "barcode listed twice",
                format!("{text}7 5\n"),
                Expect::ErrAt(text.lines().count() + 1),
            )],
        };
        let others: Vec<&str> = files.iter().map(|f| f.0).filter(|f| f != file).collect();
        let texts = &texts;
        run_variants(
            "mrclam",
            file,
            text,
            |d| {
                for (j, (f, _)) in files.iter().enumerate() {
                    if others.contains(f) {
                        std::fs::write(d.join(f), &texts[j]).unwrap();
                    }
                }
            },
            mrclam_outcome,
            extras,
            false,
        );
    }
}

fn tum_outcome(p: &Path) -> Outcome {
    tum::read_tum(p).map(|t| (t.len(), format!("{t:?}")))
}

#[test]
fn tum_malformed_variants() {
    let Some(p) = common::dataset("bench/intel.ref.tum") else {
        return;
    };
    let text = first_lines(&p, 300);
    let extras = vec![
        extra(
            "x = 2e6 m",
            edit_line(&text, 3, |f| f[1] = "2e6".into()),
            Expect::ErrAt(3),
        ),
        extra(
            "quaternion of norm 2",
            edit_line(&text, 3, |f| f[7] = "2".into()),
            Expect::ErrAt(3),
        ),
        extra(
            "time 2e7 s later",
            edit_line(&text, 3, |f| f[0] = "996052857".into()),
            Expect::ErrAt(3),
        ),
        // Repeated and backwards times are kept as given.
        extra(
            "time repeated",
            edit_line(&text, 3, |f| f[0] = "976052857.337536".into()),
            Expect::Any,
        ),
    ];
    run_variants(
        "tum",
        "t.tum",
        &text,
        |_| {},
        |d| tum_outcome(&d.join("t.tum")),
        extras,
        false,
    );
}

fn relations_outcome(p: &Path) -> Outcome {
    relations::read_relations(p).map(|r| (r.len(), format!("{r:?}")))
}

#[test]
fn relations_malformed_variants() {
    let Some(p) = common::dataset("slam-benchmark-relations/intel.relations") else {
        return;
    };
    let text = first_lines(&p, 300);
    let extras = vec![
        extra(
            "t2 = t1 + 2e7 s",
            edit_line(&text, 2, |f| f[1] = "996052911".into()),
            Expect::ErrAt(2),
        ),
        extra(
            "yaw 100 rad",
            edit_line(&text, 2, |f| f[7] = "100".into()),
            Expect::ErrAt(2),
        ),
        extra(
            "z = 1",
            edit_line(&text, 2, |f| f[4] = "1".into()),
            Expect::ErrAt(2),
        ),
        extra(
            "x = 2e6 m",
            edit_line(&text, 2, |f| f[2] = "2e6".into()),
            Expect::ErrAt(2),
        ),
    ];
    run_variants(
        "relations",
        "r.relations",
        &text,
        |_| {},
        |d| relations_outcome(&d.join("r.relations")),
        extras,
        false,
    );
}

fn csv_outcome(p: &Path) -> Outcome {
    landmarks_csv::read_landmarks_csv(p).map(|l| (l.len(), format!("{l:?}")))
}

#[test]
fn landmarks_csv_malformed_variants() {
    let Some(dir) = common::dataset("freiburg-robot-mapping") else {
        return;
    };
    // The true landmarks of world.dat, written with covariances, as the CLI writes them.
    let d = freiburg::read_freiburg(&dir).unwrap();
    let l: Vec<LandmarkEstimate> = d
        .landmarks
        .unwrap()
        .into_iter()
        .map(|(id, p)| LandmarkEstimate {
            id,
            mean: p,
            covariance: Matrix2::new(0.01 * id.0 as f64, 0.001, 0.001, 0.02),
        })
        .collect();
    let s = Scratch::new("csv-base");
    let p = s.0.join("l.csv");
    landmarks_csv::write_landmarks_csv(&p, &l).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    let extras = vec![
        extra(
            "negative variance",
            edit_line(&text, 3, |f| f[3] = "-1".into()),
            Expect::ErrAt(3),
        ),
        extra(
            "x = 2e6 m",
            edit_line(&text, 3, |f| f[1] = "2e6".into()),
            Expect::ErrAt(3),
        ),
        extra(
            "wrong header",
            text.replacen("id,x", "id,q", 1),
            Expect::ErrAt(1),
        ),
    ];
    run_variants(
        "landmarks_csv",
        "l.csv",
        &text,
        |_| {},
        |d| csv_outcome(&d.join("l.csv")),
        extras,
        false,
    );
    assert_eq!(
        landmarks_csv::read_landmarks_csv(&p).unwrap()[0].id,
        LandmarkId(1)
    );
}

fn map_outcome(p: &Path) -> Outcome {
    ros_map::read_ros_map(p).map(|m| (m.cells.len(), format!("{m:?}")))
}

/// A map rendered from the course's CSAIL log: the end points of the first scans, marked
/// occupied on a 0.1 m grid, the cells between robot and end point free.
fn csail_map() -> Option<GridMap> {
    let p = common::dataset("freiburg-robot-mapping/csail.log")?;
    let log = carmen::read_carmen(&p).unwrap();
    let mut m = GridMap::unknown(0.1, Point2::new(-10.0, -10.0), 200, 200);
    for r in log.dataset.records.iter().take(5) {
        let s = r.scan.as_ref().unwrap();
        for q in s.hit_points() {
            let w = r.odometry.transform_point(&q);
            let (i, j) = (((w.x + 10.0) / 0.1) as isize, ((w.y + 10.0) / 0.1) as isize);
            if (0..200).contains(&i) && (0..200).contains(&j) {
                m.cells[j as usize * 200 + i as usize] = 100;
            }
        }
    }
    for c in m.cells.iter_mut().filter(|c| **c < 0).step_by(3) {
        *c = 0;
    }
    Some(m)
}

#[test]
fn ros_map_malformed_variants() {
    let Some(map) = csail_map() else {
        return;
    };
    let s = Scratch::new("map-base");
    ros_map::write_ros_map(&s.0, "map", &map).unwrap();
    let yaml = std::fs::read_to_string(s.0.join("map.yaml")).unwrap();
    let pgm = std::fs::read(s.0.join("map.pgm")).unwrap();
    let with = |old: &str, new: &str| yaml.replacen(old, new, 1);
    let extras = vec![
        extra(
            "resolution 1e308",
            with("resolution: 0.1", "resolution: 1e308"),
            Expect::ErrAt(2),
        ),
        extra(
            "resolution -1",
            with("resolution: 0.1", "resolution: -1"),
            Expect::ErrAt(2),
        ),
        extra(
            "resolution NaN",
            with("resolution: 0.1", "resolution: .nan"),
            Expect::ErrAt(2),
        ),
        extra(
            "origin 1e7",
            with("origin: [-10", "origin: [1e7"),
            Expect::ErrAt(3),
        ),
        extra("origin of 2", with(", 0.0]", "]"), Expect::ErrAt(3)),
        extra("rotated origin", with(", 0.0]", ", 0.5]"), Expect::ErrAt(3)),
        extra("no image key", with("image: map.pgm\n", ""), Expect::Err),
        extra(
            "image missing",
            with("image: map.pgm", "image: none.pgm"),
            Expect::ErrNaming("none.pgm"),
        ),
        extra(
            "image is the YAML",
            with("image: map.pgm", "image: map.yaml"),
            Expect::Err,
        ),
        extra(
            "threshold 7",
            with("occupied_thresh: 0.65", "occupied_thresh: 7"),
            Expect::ErrAt(5),
        ),
        extra(
            "negate maybe",
            with("negate: 0", "negate: maybe"),
            Expect::ErrAt(4),
        ),
        extra("mode raw", format!("{yaml}mode: raw\n"), Expect::ErrAt(7)),
        extra(
            "duplicated key",
            format!("{yaml}resolution: 0.2\n"),
            Expect::Err,
        ),
        extra(
            "a list, not a mapping",
            "- image\n- map.pgm\n".into(),
            Expect::Err,
        ),
        extra("unclosed flow list", with(", 0.0]", ", 0.0"), Expect::Err),
        extra(
            "inline comments",
            yaml.replace('\n', "  # note\n"),
            Expect::Same,
        ),
        extra(
            "block-style origin",
            with(
                "origin: [-10, -10, 0.0]",
                "origin:\n  - -10\n  - -10\n  - 0",
            ),
            Expect::Same,
        ),
        extra(
            "BOM, CRLF",
            format!("\u{feff}{}", yaml.replace('\n', "\r\n")),
            Expect::Same,
        ),
        extra(
            "deep nesting",
            format!("{yaml}x:\n{}1\n", "- ".repeat(100_000)),
            Expect::Err,
        ),
    ];
    // Generic text variants do not apply to YAML's grammar; these are the YAML ones.
    let dir = Scratch::new("map");
    std::fs::write(dir.0.join("map.pgm"), &pgm).unwrap();
    let target = dir.0.join("map.yaml");
    std::fs::write(&target, &yaml).unwrap();
    let base = map_outcome(&target).unwrap();
    let mut all = extras;
    all.push(extra("empty", String::new(), Expect::Err));
    all.push(extra("garbage", "\u{1}\u{2}:::[[{{".into(), Expect::Err));
    assert!(all.len() >= 20);
    for v in &all {
        std::fs::write(&target, &v.bytes).unwrap();
        let got = no_panic(&format!("ros_map, {}", v.name), || map_outcome(&target));
        check("ros_map", v, "map.yaml", &base, got);
    }
    // Image variants: each must be refused naming the image (or read the same for PNG).
    std::fs::write(&target, &yaml).unwrap();
    let img = dir.0.join("map.pgm");
    let header_end = pgm.len() - map.cells.len();
    let png = {
        let g = image::GrayImage::from_raw(200, 200, pgm[header_end..].to_vec()).unwrap();
        let mut b = std::io::Cursor::new(Vec::new());
        g.write_to(&mut b, image::ImageFormat::Png).unwrap();
        b.into_inner()
    };
    for (name, bytes, same) in [
        ("truncated PGM", pgm[..pgm.len() - 10].to_vec(), false),
        ("PGM header only", pgm[..header_end].to_vec(), false),
        (
            "PGM 10^6 × 10^6",
            b"P5\n1000000 1000000\n255\n\0\0".to_vec(),
            false,
        ),
        ("PGM maxval 0", b"P5\n2 2\n0\n\0\0\0\0".to_vec(), false),
        ("PGM P6", b"P6\n1 1\n255\n\0\0\0".to_vec(), false),
        ("garbage", b"\x00\x01\x02garbage".to_vec(), false),
        ("empty", Vec::new(), false),
        // Read the same with the PNG decoder (feature `png`), refused naming the image without.
        ("PNG", png.clone(), cfg!(feature = "png")),
        ("truncated PNG", png[..png.len() / 2].to_vec(), false),
    ] {
        std::fs::write(&img, &bytes).unwrap();
        let got = no_panic(&format!("ros_map image, {name}"), || map_outcome(&target));
        match (same, got) {
            (true, Ok(r)) => assert!(r == base, "{name}: differs"),
            (false, Err(e)) => assert!(e.to_string().contains("map.pgm"), "{name}: {e}"),
            (_, r) => panic!("{name}: {:?}", r.map(|r| r.0)),
        }
    }
    // A folder and a missing file as the YAML.
    for p in [dir.0.clone(), dir.0.join("none.yaml")] {
        let e = no_panic("ros_map path", || ros_map::read_ros_map(&p))
            .unwrap_err()
            .to_string();
        assert!(e.contains(&*p.to_string_lossy()), "{e}");
    }
}

#[test]
fn open_dataset_on_odd_paths() {
    let s = Scratch::new("paths");
    let empty = s.0.join("empty-folder");
    std::fs::create_dir(&empty).unwrap();
    let cases: Vec<(PathBuf, Option<u32>)> = vec![
        (s.0.join("missing"), None),
        (empty.clone(), None),
        (empty.clone(), Some(1)),
        (s.0.clone(), Some(9)),
    ];
    for (p, robot) in cases {
        let e = no_panic("open_dataset", || slam::io::open_dataset(&p, robot))
            .expect_err("accepted")
            .to_string();
        assert!(e.contains(&*p.to_string_lossy()), "{e}");
    }
    // A Freiburg folder whose sensor_data.dat is a folder; an MRCLAM folder asked for robot 7.
    let f = s.0.join("freiburg");
    std::fs::create_dir_all(f.join("sensor_data.dat")).unwrap();
    let e = no_panic("open_dataset", || slam::io::open_dataset(&f, None))
        .unwrap_err()
        .to_string();
    assert!(e.contains("sensor_data.dat"), "{e}");
    if let Some(m) = common::dataset("utias-mrclam/MRCLAM_Dataset1") {
        let e = slam::io::open_dataset(&m, Some(7)).unwrap_err().to_string();
        assert!(e.contains("robot 7"), "{e}");
    }
}

// ---------------------------------------------------------------------------------------
// Property-based fuzz: random edits of real files through every reader. No panic, and what
// is accepted is within the documented bounds.

/// A random edit of a text: replace a field, delete, duplicate or cut a line, flip a byte.
#[derive(Debug, Clone)]
enum Edit {
    Field {
        line: usize,
        field: usize,
        value: &'static str,
    },
    DeleteLine(usize),
    DuplicateLine(usize),
    Truncate(usize),
    FlipByte {
        at: usize,
        to: u8,
    },
}

const VALUES: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e13",
    "-0",
    "0",
    "1e-320",
    "x",
    "",
    "99999999999999999999",
    "-1",
    "3.5",
    "1e6",
    "FLASER",
    "ODOM",
    "#",
    "\u{feff}",
];

fn edit_strategy() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (0usize..400, 0usize..400, prop::sample::select(VALUES))
            .prop_map(|(line, field, value)| Edit::Field { line, field, value }),
        (0usize..400).prop_map(Edit::DeleteLine),
        (0usize..400).prop_map(Edit::DuplicateLine),
        (0usize..1 << 20).prop_map(Edit::Truncate),
        (0usize..1 << 20, any::<u8>()).prop_map(|(at, to)| Edit::FlipByte { at, to }),
    ]
}

fn apply(text: &str, edits: &[Edit]) -> Vec<u8> {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut bytes_edits = Vec::new();
    for e in edits {
        let n = lines.len().max(1);
        match e {
            Edit::Field { line, field, value } => {
                if let Some(l) = lines.get_mut(line % n) {
                    let mut f: Vec<&str> = l.split_whitespace().collect();
                    if !f.is_empty() {
                        let k = field % f.len();
                        f[k] = value;
                        *l = f.join(" ");
                    }
                }
            }
            Edit::DeleteLine(k) if !lines.is_empty() => {
                lines.remove(k % n);
            }
            Edit::DuplicateLine(k) if !lines.is_empty() => {
                let l = lines[k % n].clone();
                lines.insert(k % n, l);
            }
            _ => bytes_edits.push(e.clone()),
        }
    }
    let mut b: Vec<u8> = lines.join("\n").into_bytes();
    b.push(b'\n');
    for e in bytes_edits {
        match e {
            Edit::Truncate(at) => b.truncate(at % (b.len() + 1)),
            Edit::FlipByte { at, to } if !b.is_empty() => {
                let k = at % b.len();
                b[k] = to;
            }
            _ => {}
        }
    }
    b
}

/// The bounds every accepted value must respect (slam_io::bounds).
fn within(v: f64, bound: f64) -> bool {
    v.is_finite() && v.abs() <= bound
}

fn fuzz_bases() -> Option<Vec<(&'static str, String)>> {
    let log = common::dataset("bench/intel.log")?;
    let tumf = common::dataset("bench/intel.ref.tum")?;
    let rel = common::dataset("slam-benchmark-relations/intel.relations")?;
    let fr = common::dataset("freiburg-robot-mapping/sensor_data.dat")?;
    let mr = common::dataset("utias-mrclam/MRCLAM_Dataset1/Robot1_Odometry.dat")?;
    Some(vec![
        ("carmen", first_lines(&log, 120)),
        ("tum", first_lines(&tumf, 60)),
        ("relations", first_lines(&rel, 60)),
        ("freiburg", first_lines(&fr, 80)),
        ("mrclam", first_lines(&mr, 80)),
    ])
}

/// Reads `bytes` with reader `which` and checks what is accepted against the bounds.
fn fuzz_one(which: &str, bytes: &[u8], dir: &Path) {
    use slam::io::bounds::{MAX_COORD, MAX_HEADING, MAX_RANGE, MAX_TIME};
    let ok_pose = |p: &slam::models::Pose2| {
        within(p.x, MAX_COORD) && within(p.y, MAX_COORD) && within(p.theta, MAX_HEADING)
    };
    match which {
        "carmen" => {
            let p = dir.join("f.log");
            std::fs::write(&p, bytes).unwrap();
            if let Ok(l) = no_panic("carmen fuzz", || carmen::read_carmen(&p)) {
                for r in &l.dataset.records {
                    assert!(within(r.t, MAX_TIME) && ok_pose(&r.odometry), "{r:?}");
                    if let Some(s) = &r.scan {
                        assert!(s.ranges.iter().all(|&x| (0.0..=MAX_RANGE).contains(&x)));
                        assert!(s.max_range > 0.0 && s.max_range <= MAX_RANGE);
                    }
                }
            }
        }
        "tum" => {
            let p = dir.join("f.tum");
            std::fs::write(&p, bytes).unwrap();
            if let Ok(t) = no_panic("tum fuzz", || tum::read_tum(&p)) {
                assert!(t.iter().all(|p| within(p.t, MAX_TIME) && ok_pose(&p.pose)));
            }
        }
        "relations" => {
            let p = dir.join("f.relations");
            std::fs::write(&p, bytes).unwrap();
            if let Ok(r) = no_panic("relations fuzz", || relations::read_relations(&p)) {
                assert!(r.iter().all(|r| within(r.t1, MAX_TIME)
                    && within(r.t2, 2.0 * MAX_TIME)
                    && ok_pose(&r.delta)));
            }
        }
        "freiburg" => {
            std::fs::write(dir.join("sensor_data.dat"), bytes).unwrap();
            if let Ok(d) = no_panic("freiburg fuzz", || freiburg::read_freiburg(dir)) {
                for s in &d.steps {
                    assert!(s.control.validate().is_ok());
                    assert!(s
                        .observations
                        .iter()
                        .all(|z| (0.0..=MAX_RANGE).contains(&z.range) && within(z.bearing, 7.0)));
                }
            }
        }
        _ => {
            let p = dir.join("f.dat");
            std::fs::write(&p, bytes).unwrap();
            std::fs::write(dir.join("Robot1_Odometry.dat"), bytes).unwrap();
            if let Ok(d) = no_panic("mrclam fuzz", || mrclam::read_mrclam(dir, 1)) {
                assert!(d
                    .steps
                    .iter()
                    .all(|s| within(s.t, MAX_TIME) && s.control.validate().is_ok()));
            }
        }
    }
}

proptest! {
    // Fixed case count and no persistence file: the same few seconds on every run.
    #![proptest_config(ProptestConfig { cases: 48, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn fuzz_every_reader(edits in prop::collection::vec(edit_strategy(), 1..6)) {
        let Some(bases) = fuzz_bases() else { return Ok(()); };
        let dir = Scratch::new("fuzz");
        if let Some(m) = common::dataset("utias-mrclam/MRCLAM_Dataset1") {
            std::fs::write(dir.0.join("Barcodes.dat"), std::fs::read(m.join("Barcodes.dat")).unwrap()).unwrap();
            std::fs::write(dir.0.join("Landmark_Groundtruth.dat"), std::fs::read(m.join("Landmark_Groundtruth.dat")).unwrap()).unwrap();
            std::fs::write(dir.0.join("Robot1_Measurement.dat"), first_lines(&m.join("Robot1_Measurement.dat"), 40)).unwrap();
        }
        for (which, text) in &bases {
            let bytes = apply(text, &edits);
            fuzz_one(which, &bytes, &dir.0);
        }
        // The map YAML too: edits of a valid description, the image left alone.
        let m = GridMap::unknown(0.05, Point2::new(-1.0, 2.0), 3, 2);
        ros_map::write_ros_map(&dir.0, "map", &m).unwrap();
        let yaml = std::fs::read_to_string(dir.0.join("map.yaml")).unwrap();
        std::fs::write(dir.0.join("map.yaml"), apply(&yaml, &edits)).unwrap();
        if let Ok(g) = no_panic("ros_map fuzz", || ros_map::read_ros_map(&dir.0.join("map.yaml"))) {
            prop_assert!(g.resolution > 0.0 && g.resolution <= 1e3 && g.cells.len() == 6);
            prop_assert!(within(g.origin.x, 1e6) && within(g.origin.y, 1e6));
        }
    }
}

// ---------------------------------------------------------------------------------------
// Regressions: one test for each reader defect listed in issue 17.

/// Issue 17: "ranges, poses and times like 1e308 pass every reader". One value per reader
/// and kind, in a real file; each must be a file:line error naming the field.
#[test]
fn regression_1e308_is_refused_by_every_reader() {
    let (Some(log), Some(tumf), Some(rel), Some(fr)) = (
        common::dataset("bench/intel.log"),
        common::dataset("bench/intel.ref.tum"),
        common::dataset("slam-benchmark-relations/intel.relations"),
        common::dataset("freiburg-robot-mapping"),
    ) else {
        return;
    };
    let s = Scratch::new("reg-1e308");
    let carmen_text = first_lines(&log, 200);
    let fl = line_starting(&carmen_text, "FLASER");
    let od = line_starting(&carmen_text, "ODOM");
    for (line, field, what) in [
        (fl, 20, "range reading 19"),
        (fl, 182, "laser pose x"),
        (od, 1, "odometry pose x"),
        (od, 7, "ipc_timestamp"),
    ] {
        let p = s.0.join("r.log");
        std::fs::write(
            &p,
            edit_line(&carmen_text, line, |f| f[field] = "1e308".into()),
        )
        .unwrap();
        let e = carmen::read_carmen(&p).unwrap_err().to_string();
        assert!(
            e.contains(&format!("r.log:{line}: {what}")) && e.contains("1e308"),
            "{e}"
        );
    }
    let tum_text = first_lines(&tumf, 20);
    for (field, what) in [(0, "timestamp"), (1, "x")] {
        let p = s.0.join("t.tum");
        std::fs::write(&p, edit_line(&tum_text, 4, |f| f[field] = "1e308".into())).unwrap();
        let e = tum::read_tum(&p).unwrap_err().to_string();
        assert!(
            e.contains(&format!("t.tum:4: {what} = 1e308 is out of bounds")),
            "{e}"
        );
    }
    let rel_text = first_lines(&rel, 20);
    let p = s.0.join("r.relations");
    std::fs::write(&p, edit_line(&rel_text, 4, |f| f[0] = "1e308".into())).unwrap();
    let e = relations::read_relations(&p).unwrap_err().to_string();
    assert!(e.contains("r.relations:4: t1 = 1e308"), "{e}");
    let sensor = std::fs::read_to_string(fr.join("sensor_data.dat")).unwrap();
    let se = line_starting(&sensor, "SENSOR");
    std::fs::write(
        s.0.join("sensor_data.dat"),
        edit_line(&sensor, se, |f| f[2] = "1e308".into()),
    )
    .unwrap();
    let e = freiburg::read_freiburg(&s.0).unwrap_err().to_string();
    assert!(
        e.contains(&format!("sensor_data.dat:{se}: range = 1e308")),
        "{e}"
    );
}

/// Issue 17: "ROBOTLASER1 start angle, field of view and angular resolution are only checked
/// for finiteness". The course's CSAIL log with each one made absurd.
#[test]
fn regression_robotlaser1_geometry_is_checked() {
    let Some(p) = common::dataset("freiburg-robot-mapping/csail.log") else {
        return;
    };
    let text = first_lines(&p, 3);
    let s = Scratch::new("reg-rl1");
    let q = s.0.join("c.log");
    // Fields: 2 start_angle, 3 fov, 4 angular_res (361 beams of 0.008727 rad, fov 3.150447).
    for (field, value, what) in [
        (2, "1e5", "start_angle"),
        (3, "1e-300", "fov"),
        (3, "100", "fov"),
        (4, "0", "angular_res"),
        // A resolution of 1e-9 rad is in range but cannot span the stated fov with N beams.
        (4, "1e-9", "fov"),
        (4, "4", "angular_res"),
    ] {
        std::fs::write(&q, edit_line(&text, 2, |f| f[field] = value.into())).unwrap();
        let e = carmen::read_carmen(&q).unwrap_err().to_string();
        assert!(
            e.contains(&format!("c.log:2: {what} = ")),
            "{field}={value}: {e}"
        );
    }
    std::fs::write(&q, &text).unwrap();
    assert_eq!(carmen::read_carmen(&q).unwrap().dataset.records.len(), 3);
}

/// Issue 17: "one outlier reading in a FLASER log changes which readings count as no return
/// for the whole log". One reading of Intel's log set to 500 m (and, separately, to 90 m):
/// the no-return value stays 81.83 (the README's, counted independently), and every other
/// reading is a hit or not exactly as before.
#[test]
fn regression_one_outlier_does_not_move_the_no_return_value() {
    let Some(log) = common::dataset("bench/intel.log") else {
        return;
    };
    let text = std::fs::read_to_string(&log).unwrap();
    let base = carmen::read_carmen(&log).unwrap();
    assert_eq!(base.flaser_max_range, Some(81.83));
    let fl = line_starting(&text, "FLASER");
    let s = Scratch::new("reg-outlier");
    let p = s.0.join("o.log");
    for outlier in ["500", "90"] {
        std::fs::write(&p, edit_line(&text, fl, |f| f[10] = outlier.into())).unwrap();
        let got = carmen::read_carmen(&p).unwrap();
        assert_eq!(got.flaser_max_range, Some(81.83), "outlier {outlier}");
        let hits = |l: &carmen::CarmenLog| -> Vec<bool> {
            l.dataset
                .records
                .iter()
                .filter_map(|r| r.scan.as_ref())
                .flat_map(|s| (0..s.len()).map(move |k| s.is_hit(k)))
                .collect()
        };
        let (a, b) = (hits(&base), hits(&got));
        let changed: Vec<usize> = (0..a.len()).filter(|&k| a[k] != b[k]).collect();
        // Only the corrupted reading itself (beam 8 of the first scan) may change, and it
        // is not a hit: above the no-return value it is a no-return.
        assert!(
            changed.len() <= 1 && !b[8],
            "outlier {outlier}: {changed:?}"
        );
    }
}

/// Issue 17: "a multi-member .gz log is read only up to its first member". A Radish log
/// recompressed as two members reads exactly as the original file.
#[test]
fn regression_multi_member_gzip_is_read_whole() {
    let Some(p) = common::dataset("radish-corrected/intel-corrected.log.gz") else {
        return;
    };
    let whole = carmen::read_carmen(&p).unwrap();
    let mut text = String::new();
    std::io::Read::read_to_string(
        &mut flate2::read::MultiGzDecoder::new(std::fs::File::open(&p).unwrap()),
        &mut text,
    )
    .unwrap();
    let cut = half_at_line(&text);
    let s = Scratch::new("reg-gz");
    let q = s.0.join("intel-corrected.log.gz");
    std::fs::write(
        &q,
        [gzip(&text.as_bytes()[..cut]), gzip(&text.as_bytes()[cut..])].concat(),
    )
    .unwrap();
    let two = carmen::read_carmen(&q).unwrap();
    assert_eq!(two.dataset, whole.dataset);
    assert_eq!(two.dataset.records.len(), 910 + 14541);
}

/// Issue 17: "files that start with a UTF-8 byte-order mark" were refused. Real files with
/// a BOM read as without.
#[test]
fn regression_byte_order_mark_is_accepted() {
    let (Some(log), Some(tumf)) = (
        common::dataset("bench/fhw.log"),
        common::dataset("bench/fhw.ref.tum"),
    ) else {
        return;
    };
    let s = Scratch::new("reg-bom");
    let p = s.0.join("fhw.log");
    std::fs::write(
        &p,
        [&[0xef, 0xbb, 0xbf][..], &std::fs::read(&log).unwrap()].concat(),
    )
    .unwrap();
    assert_eq!(
        carmen::read_carmen(&p).unwrap().dataset,
        carmen::read_carmen(&log).unwrap().dataset
    );
    let q = s.0.join("fhw.ref.tum");
    std::fs::write(
        &q,
        [&[0xef, 0xbb, 0xbf][..], &std::fs::read(&tumf).unwrap()].concat(),
    )
    .unwrap();
    assert_eq!(tum::read_tum(&q).unwrap(), tum::read_tum(&tumf).unwrap());
}

/// Issue 17: "map.yaml with inline comments or flow-style lists" and "PNG map images" were
/// refused. A map_server description as people write it, with a PNG image.
#[test]
#[cfg(feature = "png")]
fn regression_map_yaml_comments_and_png_images() {
    let Some(map) = csail_map() else {
        return;
    };
    let s = Scratch::new("reg-yaml");
    ros_map::write_ros_map(&s.0, "map", &map).unwrap();
    let pgm = std::fs::read(s.0.join("map.pgm")).unwrap();
    let g =
        image::GrayImage::from_raw(200, 200, pgm[pgm.len() - map.cells.len()..].to_vec()).unwrap();
    g.save(s.0.join("map.png")).unwrap();
    std::fs::write(
        s.0.join("edited.yaml"),
        "image: map.png   # saved by hand\nresolution: 0.100 # m/cell\n\
         origin: [-10.0,   -10.0, 0.0]  # lower-left pixel\nnegate: 0\n\
         occupied_thresh: 0.65\nfree_thresh: 0.196\n",
    )
    .unwrap();
    let a = ros_map::read_ros_map(&s.0.join("map.yaml")).unwrap();
    let b = ros_map::read_ros_map(&s.0.join("edited.yaml")).unwrap();
    assert_eq!(a, b);
    // The written map reads back as its trinary self: occupied where the scans ended.
    assert_eq!(
        a.cells.iter().filter(|&&c| c == 100).count(),
        map.cells.iter().filter(|&&c| c == 100).count()
    );
}

/// Issue 17: "a RAWLASER1 log runs the whole filter on odometry alone and then fails with
/// 'grid has 0 cells'". Intel's bench log with every FLASER line rewritten as the RAWLASER1
/// line CARMEN would have logged for it: the scans are read, with the same readings, and
/// placed at the odometry pose the FLASER line carried (each FLASER follows an ODOM record of
/// its own time); the same log with its scans removed is refused naming what it holds.
#[test]
fn regression_rawlaser1_logs_are_read() {
    let Some(log) = common::dataset("bench/intel.log") else {
        return;
    };
    let text = std::fs::read_to_string(&log).unwrap();
    let base = carmen::read_carmen(&log).unwrap();
    let raw: String = text
        .lines()
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            if f.first() != Some(&"FLASER") {
                return format!("{l}\n");
            }
            let n: usize = f[1].parse().unwrap();
            // 180 beams: −90° … +89° in 1° steps, fov 180°, no-return code 81.83 m.
            format!(
                "RAWLASER1 0 -1.5707963267948966 3.141592653589793 0.017453292519943295 81.83 0.01 0 {n} {} 0 {}\n",
                f[2..2 + n].join(" "),
                f[f.len() - 3..].join(" ")
            )
        })
        .collect();
    let s = Scratch::new("reg-raw");
    let p = s.0.join("intel-raw.log");
    std::fs::write(&p, &raw).unwrap();
    let got = carmen::read_carmen(&p).unwrap();
    let scans = |l: &carmen::CarmenLog| -> Vec<(f64, slam::models::Pose2, Vec<f64>)> {
        l.dataset
            .records
            .iter()
            .filter_map(|r| r.scan.as_ref().map(|s| (r.t, r.odometry, s.ranges.clone())))
            .collect()
    };
    let (a, b) = (scans(&base), scans(&got));
    assert_eq!(a.len(), 910);
    assert_eq!(b.len(), 910);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!((x.0, &x.2), (y.0, &y.2));
        assert!(x.1.approx_eq(&y.1, 1e-12), "{:?} vs {:?}", x.1, y.1);
    }
    let scan = got
        .dataset
        .records
        .iter()
        .find_map(|r| r.scan.as_ref())
        .unwrap();
    assert_eq!(scan.max_range, 81.83);
    assert!((scan.beam_angle(179).to_degrees() - 89.0).abs() < 1e-9);
    // Without its scans the log holds only odometry: refused at load, saying what it holds.
    let odom_only: String = text
        .lines()
        .filter(|l| !l.starts_with("FLASER"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&p, odom_only).unwrap();
    let e = carmen::read_carmen(&p).unwrap_err().to_string();
    assert!(
        e.contains("no usable laser scan") && e.contains("the log holds 13700 ODOM"),
        "{e}"
    );
}
