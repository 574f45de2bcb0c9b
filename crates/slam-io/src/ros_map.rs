//! ROS `map_server` maps: a PGM image and a YAML description (the format `map_saver`
//! writes and `map_server` loads).
//!
//! The YAML holds `image`, `resolution` (m/cell), `origin` [x, y, yaw] (the world pose of
//! the **lower-left** pixel), `negate`, `occupied_thresh` and `free_thresh`. The image is a
//! binary PGM (P5, maxval 255) whose first row is the **top** of the map (largest y).
//!
//! Writing uses map_saver's trinary encoding of a [`GridMap`] (values −1 unknown, 0…100
//! occupancy in percent): occupied (≥ 65) → 0 (black), free (≤ 25) → 254 (white),
//! anything else, including unknown, → 205 (grey); with `negate: 0`,
//! `occupied_thresh: 0.65`, `free_thresh: 0.196`.
//!
//! Reading follows map_server's trinary interpretation: p = (255 − v)/255 (or v/255 when
//! `negate: 1`); p > occupied_thresh → 100, p < free_thresh → 0, otherwise −1. A written
//! map therefore reads back as the trinary version of itself.

use crate::error::IoError;
use slam_models::{GridMap, Point2};
use std::collections::HashMap;
use std::io::Write;
use std::path::Path;

/// Occupancy (percent) at or above which a cell is written as occupied.
pub const OCCUPIED_PERCENT: i8 = 65;
/// Occupancy (percent) at or below which a cell is written as free.
pub const FREE_PERCENT: i8 = 25;

/// Writes `<dir>/<stem>.pgm` and `<dir>/<stem>.yaml` (the YAML's `image` is the PGM's
/// file name, relative to the YAML). Errors: a grid whose cell count is not width·height,
/// a non-positive or non-finite resolution or origin, or an I/O failure.
pub fn write_ros_map(dir: &Path, stem: &str, m: &GridMap) -> Result<(), IoError> {
    let pgm = dir.join(format!("{stem}.pgm"));
    let yaml = dir.join(format!("{stem}.yaml"));
    if m.cells.len() != m.width * m.height || m.width == 0 || m.height == 0 {
        return Err(IoError::invalid(
            &pgm,
            format!(
                "grid has {} cells, expected width·height = {}·{} > 0",
                m.cells.len(),
                m.width,
                m.height
            ),
        ));
    }
    if !(m.resolution.is_finite()
        && m.resolution > 0.0
        && m.origin.x.is_finite()
        && m.origin.y.is_finite())
    {
        return Err(IoError::invalid(
            &yaml,
            "resolution must be finite and > 0, origin finite",
        ));
    }
    std::fs::create_dir_all(dir).map_err(|e| IoError::io(dir, e))?;
    let mut bytes = format!(
        "P5\n# slam-rs occupancy map, {} m/cell\n{} {}\n255\n",
        m.resolution, m.width, m.height
    )
    .into_bytes();
    bytes.reserve(m.cells.len());
    for row in (0..m.height).rev() {
        for &v in &m.cells[row * m.width..(row + 1) * m.width] {
            bytes.push(if v >= OCCUPIED_PERCENT {
                0
            } else if (0..=FREE_PERCENT).contains(&v) {
                254
            } else {
                205
            });
        }
    }
    let write = |p: &Path, b: &[u8]| -> Result<(), IoError> {
        let mut f = std::fs::File::create(p).map_err(|e| IoError::io(p, e))?;
        f.write_all(b).map_err(|e| IoError::io(p, e))
    };
    write(&pgm, &bytes)?;
    let y = format!(
        "image: {stem}.pgm\nresolution: {}\norigin: [{}, {}, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
        m.resolution, m.origin.x, m.origin.y
    );
    write(&yaml, y.as_bytes())
}

/// Reads a map_server YAML and the image it names (a PGM, P5 or P2, relative to the YAML's
/// folder). Errors: missing keys, malformed values, a non-zero origin yaw (rotated maps are
/// not representable in [`GridMap`]), a malformed or short image.
pub fn read_ros_map(yaml: &Path) -> Result<GridMap, IoError> {
    let text = crate::text::read_text(yaml)?;
    text.ensure_not_empty("map_server keys image, resolution, origin, …")?;
    let mut keys: HashMap<&str, (usize, &str)> = HashMap::new();
    for l in text.data_lines() {
        let Some((k, v)) = l.text.split_once(':') else {
            return Err(l.error("`key: value`", l.text));
        };
        keys.insert(k.trim(), (l.no, v.trim()));
    }
    let get = |k: &str| -> Result<(usize, &str), IoError> {
        keys.get(k).copied().ok_or_else(|| IoError::Parse {
            path: yaml.to_path_buf(),
            line: 0,
            expected: format!("a `{k}:` entry"),
            found: "none".into(),
        })
    };
    let num = |k: &str, s: &str, line: usize| -> Result<f64, IoError> {
        s.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| IoError::Parse {
                path: yaml.to_path_buf(),
                line,
                expected: format!("{k}: a finite number"),
                found: s.to_string(),
            })
    };
    let (li, image) = get("image")?;
    let (lr, res) = get("resolution")?;
    let res = num("resolution", res, lr)?;
    if res <= 0.0 {
        return Err(IoError::Parse {
            path: yaml.to_path_buf(),
            line: lr,
            expected: "resolution > 0".into(),
            found: res.to_string(),
        });
    }
    let (lo, origin) = get("origin")?;
    let inner = origin
        .trim()
        .strip_prefix('[')
        .and_then(|s| s.strip_suffix(']'));
    let parts: Vec<&str> = inner
        .map(|s| s.split(',').map(str::trim).collect())
        .unwrap_or_default();
    if parts.len() != 3 {
        return Err(IoError::Parse {
            path: yaml.to_path_buf(),
            line: lo,
            expected: "origin: [x, y, yaw]".into(),
            found: origin.to_string(),
        });
    }
    let (ox, oy, yaw) = (
        num("origin x", parts[0], lo)?,
        num("origin y", parts[1], lo)?,
        num("origin yaw", parts[2], lo)?,
    );
    if yaw != 0.0 {
        return Err(IoError::Parse {
            path: yaml.to_path_buf(),
            line: lo,
            expected: "origin yaw 0 (rotated maps are not supported)".into(),
            found: origin.to_string(),
        });
    }
    let opt = |k: &str, default: f64| -> Result<f64, IoError> {
        match keys.get(k) {
            Some(&(l, v)) => num(k, v, l),
            None => Ok(default),
        }
    };
    let negate = opt("negate", 0.0)? != 0.0;
    let occ = opt("occupied_thresh", 0.65)?;
    let free = opt("free_thresh", 0.196)?;
    let image = image.trim_matches(|c| c == '"' || c == '\'');
    if image.is_empty() {
        return Err(IoError::Parse {
            path: yaml.to_path_buf(),
            line: li,
            expected: "image: a file name".into(),
            found: String::new(),
        });
    }
    let img_path = yaml.parent().unwrap_or(Path::new(".")).join(image);
    let (w, h, pix) = read_pgm(&img_path)?;
    let mut cells = vec![GridMap::UNKNOWN; w * h];
    for row in 0..h {
        for col in 0..w {
            let v = pix[row * w + col] as f64;
            let p = if negate {
                v / 255.0
            } else {
                (255.0 - v) / 255.0
            };
            cells[(h - 1 - row) * w + col] = if p > occ {
                100
            } else if p < free {
                0
            } else {
                GridMap::UNKNOWN
            };
        }
    }
    Ok(GridMap {
        resolution: res,
        origin: Point2::new(ox, oy),
        width: w,
        height: h,
        cells,
    })
}

/// A PGM image (P5 binary or P2 ASCII, maxval ≤ 255): (width, height, pixels, top row first).
fn read_pgm(path: &Path) -> Result<(usize, usize, Vec<u8>), IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
    let bad = |expected: &str| IoError::Parse {
        path: path.to_path_buf(),
        line: 1,
        expected: expected.into(),
        found: "malformed PGM header".into(),
    };
    // Header tokens, skipping comments.
    let mut pos = 0;
    let mut tokens: Vec<String> = Vec::new();
    while tokens.len() < 4 {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if pos >= bytes.len() {
            return Err(bad("a PGM header `P5 width height maxval`"));
        }
        if bytes[pos] == b'#' {
            while pos < bytes.len() && bytes[pos] != b'\n' {
                pos += 1;
            }
            continue;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        tokens.push(String::from_utf8_lossy(&bytes[start..pos]).into_owned());
    }
    let magic = tokens[0].as_str();
    let w: usize = tokens[1].parse().map_err(|_| bad("an image width"))?;
    let h: usize = tokens[2].parse().map_err(|_| bad("an image height"))?;
    let maxval: usize = tokens[3].parse().map_err(|_| bad("a maxval"))?;
    if maxval == 0 || maxval > 255 || w == 0 || h == 0 {
        return Err(bad("width, height > 0 and 0 < maxval ≤ 255"));
    }
    let scale = |v: usize| ((v.min(maxval) * 255) / maxval) as u8;
    let n = w
        .checked_mul(h)
        .ok_or_else(|| bad("a sensible image size"))?;
    match magic {
        "P5" => {
            let data = &bytes[(pos + 1).min(bytes.len())..];
            if data.len() < n {
                return Err(IoError::invalid(
                    path,
                    format!("image data too short: {} of {n} pixels", data.len()),
                ));
            }
            Ok((w, h, data[..n].iter().map(|&v| scale(v as usize)).collect()))
        }
        "P2" => {
            let rest = String::from_utf8_lossy(&bytes[pos..]);
            let vals: Result<Vec<u8>, _> = rest
                .split_whitespace()
                .take(n)
                .map(|t| t.parse::<usize>().map(scale))
                .collect();
            let vals = vals.map_err(|_| bad("pixel values"))?;
            if vals.len() < n {
                return Err(IoError::invalid(
                    path,
                    format!("image data too short: {} of {n} pixels", vals.len()),
                ));
            }
            Ok((w, h, vals))
        }
        _ => Err(bad("a P5 or P2 PGM image")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("slam-io-rosmap-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn trinary_round_trip_and_orientation() {
        let mut m = GridMap::unknown(0.05, Point2::new(-1.5, 2.0), 4, 3);
        m.cells = vec![100, 0, -1, 50, 0, 0, 0, 0, 80, 10, 30, 100];
        let d = tmp("rt");
        write_ros_map(&d, "map", &m).unwrap();
        let y = std::fs::read_to_string(d.join("map.yaml")).unwrap();
        assert!(
            y.contains("image: map.pgm") && y.contains("origin: [-1.5, 2, 0.0]"),
            "{y}"
        );
        // Top image row is the map's top row (iy = 2): 80 10 30 100 → 0 254 205 0.
        let pgm = std::fs::read(d.join("map.pgm")).unwrap();
        let n = pgm.len();
        assert_eq!(&pgm[n - 12..n - 8], &[0, 254, 205, 0]);
        let back = read_ros_map(&d.join("map.yaml")).unwrap();
        assert_eq!(
            back.cells,
            vec![100, 0, -1, -1, 0, 0, 0, 0, 100, 0, -1, 100]
        );
        assert_eq!(
            (back.width, back.height, back.resolution, back.origin),
            (4, 3, 0.05, m.origin)
        );
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn error_paths() {
        let d = tmp("err");
        let y = d.join("m.yaml");
        for (text, want) in [
            ("", "empty"),
            ("image m.pgm\n", "`key: value`"),
            ("image: m.pgm\n", "resolution"),
            (
                "image: m.pgm\nresolution: x\norigin: [0, 0, 0]\n",
                "finite number",
            ),
            (
                "image: m.pgm\nresolution: 0.1\norigin: [0, 0]\n",
                "[x, y, yaw]",
            ),
            (
                "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0.5]\n",
                "yaw 0",
            ),
            (
                "image: none.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n",
                "none.pgm",
            ),
        ] {
            std::fs::write(&y, text).unwrap();
            let e = read_ros_map(&y).unwrap_err().to_string();
            assert!(e.contains(want), "{text:?} → {e}");
        }
        std::fs::write(&y, "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n").unwrap();
        std::fs::write(d.join("m.pgm"), b"P5\n4 4\n255\n\x00\x00").unwrap();
        assert!(read_ros_map(&y)
            .unwrap_err()
            .to_string()
            .contains("too short"));
        std::fs::write(d.join("m.pgm"), b"P6\n1 1\n255\n\x00").unwrap();
        assert!(read_ros_map(&y)
            .unwrap_err()
            .to_string()
            .contains("P5 or P2"));
        std::fs::write(d.join("m.pgm"), b"P2\n2 1\n100\n0 100\n").unwrap();
        let m = read_ros_map(&y).unwrap();
        assert_eq!(m.cells, vec![100, 0]);
        let bad = GridMap {
            resolution: 0.1,
            origin: Point2::origin(),
            width: 2,
            height: 2,
            cells: vec![0],
        };
        assert!(write_ros_map(&d, "x", &bad).is_err());
        std::fs::remove_dir_all(&d).ok();
    }
}
