//! ROS `map_server` maps: a PGM image and a YAML description (the format `map_saver`
//! writes and `map_server` loads).
//!
//! The YAML holds `image`, `resolution` (m/cell), `origin` [x, y, yaw] (the world pose of
//! the **lower-left** pixel), `negate`, `occupied_thresh` and `free_thresh`. The image is a
//! binary PGM (P5, maxval 255) whose first row is the **top** of the map (largest y). On
//! reading, the YAML goes through a real YAML parser and the image may also be an ASCII PGM
//! (P2) or a PNG, as map_server reads them (see [`read_ros_map`]).
//!
//! Writing uses map_saver's trinary encoding of a [`GridMap`] (values −1 unknown, 0…100
//! occupancy in percent): occupied (≥ 65) → 0 (black), free (≤ 25) → 254 (white),
//! anything else, including unknown, → 205 (grey); with `negate: 0`,
//! `occupied_thresh: 0.65`, `free_thresh: 0.196`.
//!
//! Reading follows map_server's trinary interpretation: p = (255 − v)/255 (or v/255 when
//! `negate: 1`); p > occupied_thresh → 100, p < free_thresh → 0, otherwise −1. A written
//! map therefore reads back as the trinary version of itself.

use crate::bounds::{MAX_COORD, MAX_MAP_CELLS, RESOLUTION_RANGE};
use crate::error::IoError;
use slam_models::{GridMap, Point2};
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
    // Written row by row (a map-sized byte buffer would add to the peak of a run's end).
    let write_pgm = || -> std::io::Result<()> {
        let mut f = std::io::BufWriter::new(std::fs::File::create(&pgm)?);
        write!(
            f,
            "P5\n# slam-rs occupancy map, {} m/cell\n{} {}\n255\n",
            m.resolution, m.width, m.height
        )?;
        let mut line = Vec::with_capacity(m.width);
        for row in (0..m.height).rev() {
            line.clear();
            line.extend(
                m.cells[row * m.width..(row + 1) * m.width]
                    .iter()
                    .map(|&v| {
                        if v >= OCCUPIED_PERCENT {
                            0
                        } else if (0..=FREE_PERCENT).contains(&v) {
                            254
                        } else {
                            205
                        }
                    }),
            );
            f.write_all(&line)?;
        }
        f.flush()
    };
    write_pgm().map_err(|e| IoError::io(&pgm, e))?;
    let write = |p: &Path, b: &[u8]| -> Result<(), IoError> {
        let mut f = std::fs::File::create(p).map_err(|e| IoError::io(p, e))?;
        f.write_all(b).map_err(|e| IoError::io(p, e))
    };
    let y = format!(
        "image: {stem}.pgm\nresolution: {}\norigin: [{}, {}, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
        m.resolution, m.origin.x, m.origin.y
    );
    write(&yaml, y.as_bytes())
}

/// Largest map YAML, bytes: a map_server description is a few hundred bytes.
pub const MAX_YAML_BYTES: u64 = 1 << 20;
/// Deepest nesting of lists and maps accepted in a map YAML.
const MAX_YAML_NESTING: usize = 64;

/// The map_server description, as read from the YAML.
struct MapYaml {
    image: String,
    resolution: f64,
    origin: Point2,
    negate: bool,
    occupied_thresh: f64,
    free_thresh: f64,
    scale: bool,
}

/// Reads a map_server YAML and the image it names (relative to the YAML's folder, or
/// absolute): a PGM (P5 or P2, maxval ≤ 255) or a PNG (grey or colour, with or without
/// alpha, 8 or 16 bits), told apart by content.
///
/// The YAML is parsed by a YAML 1.2 parser ([`saphyr`]), so comments, quoting and
/// flow- or block-style lists are accepted as map_server accepts them. Keys: `image`,
/// `resolution` (within 10⁻⁴ … 10³ m/cell), `origin` (`[x, y, yaw]`, x and y within ±10⁶ m,
/// yaw 0: rotated maps are not representable in [`GridMap`]), and optionally `negate`
/// (0/1 or false/true, default 0), `occupied_thresh` (default 0.65) and `free_thresh`
/// (default 0.196), both within 0 … 1, and `mode` (`trinary`, the default, or `scale`;
/// `raw` is refused). Other keys are ignored, as map_server ignores them; a duplicated key
/// is an error.
///
/// Pixels as map_server reads them: the mean of the colour channels (alpha excluded), c;
/// p = (255 − c)/255, or c/255 with `negate`; p > occupied_thresh → 100, p < free_thresh →
/// 0, otherwise −1 in `trinary` mode; in `scale` mode a fully transparent pixel → −1 and
/// the rest 1 + ⌊98·(p − free)/(occupied − free)⌋. The first image row is the map's top.
///
/// Errors: a YAML syntax error (with its line), a missing key, a value of the wrong type or
/// out of bounds (with its line), a missing, malformed or truncated image, an image of more
/// than 2²⁸ pixels, or a map reaching beyond ±10⁶ m.
pub fn read_ros_map(yaml: &Path) -> Result<GridMap, IoError> {
    let text = crate::text::read_text_limited(yaml, MAX_YAML_BYTES)?;
    let d = parse_map_yaml(&text)?;
    let img_path = yaml.parent().unwrap_or(Path::new(".")).join(&d.image);
    let (w, h, pix) = read_map_image(&img_path)?;
    let far_x = d.origin.x + w as f64 * d.resolution;
    let far_y = d.origin.y + h as f64 * d.resolution;
    if far_x.abs() > MAX_COORD || far_y.abs() > MAX_COORD {
        return Err(IoError::invalid(
            yaml,
            format!(
                "the map's far corner ({far_x}, {far_y}) m is beyond ±{MAX_COORD} m \
                 (origin + {w}×{h} pixels × resolution)"
            ),
        ));
    }
    let mut cells = vec![GridMap::UNKNOWN; w * h];
    for row in 0..h {
        for col in 0..w {
            let (c, alpha) = pix[row * w + col];
            let p = if d.negate {
                c / 255.0
            } else {
                (255.0 - c) / 255.0
            };
            cells[(h - 1 - row) * w + col] = if p > d.occupied_thresh {
                100
            } else if p < d.free_thresh {
                0
            } else if !d.scale || alpha == 0 {
                GridMap::UNKNOWN
            } else {
                let ratio = (p - d.free_thresh) / (d.occupied_thresh - d.free_thresh);
                (1.0 + 98.0 * ratio).clamp(1.0, 99.0) as i8
            };
        }
    }
    Ok(GridMap {
        resolution: d.resolution,
        origin: d.origin,
        width: w,
        height: h,
        cells,
    })
}

/// Parses a map_server YAML description (see [`read_ros_map`]).
fn parse_map_yaml(f: &crate::text::TextFile) -> Result<MapYaml, IoError> {
    use saphyr::{LoadableYamlNode, MarkedYaml, Scalar, YamlData};
    let path = f.path.as_path();
    let err = |line: usize, expected: &str, found: &str| IoError::Parse {
        path: path.to_path_buf(),
        line,
        expected: expected.to_string(),
        found: found.chars().take(60).collect(),
    };
    f.ensure_not_empty("map_server keys image, resolution, origin, …")?;
    // Nesting depth first, from the parser's events: the node tree is built and dropped
    // recursively, so a deep one ("- - - - …") would overflow the stack.
    let mut depth = 0usize;
    for ev in saphyr_parser::Parser::new_from_str(&f.text) {
        let (ev, span) = ev.map_err(|e| {
            err(
                e.marker().line().max(1),
                "a YAML map_server description",
                e.info(),
            )
        })?;
        match ev {
            saphyr_parser::Event::SequenceStart(..) | saphyr_parser::Event::MappingStart(..) => {
                depth += 1;
                if depth > MAX_YAML_NESTING {
                    return Err(err(
                        span.start.line().max(1),
                        &format!("at most {MAX_YAML_NESTING} nested lists or maps"),
                        "deeper nesting",
                    ));
                }
            }
            saphyr_parser::Event::SequenceEnd | saphyr_parser::Event::MappingEnd => {
                depth = depth.saturating_sub(1)
            }
            _ => {}
        }
    }
    let docs = MarkedYaml::load_from_str(&f.text).map_err(|e| {
        err(
            e.marker().line().max(1),
            "a YAML map_server description",
            e.info(),
        )
    })?;
    let [doc] = docs.as_slice() else {
        return Err(IoError::invalid(
            path,
            format!("expected one YAML document, found {}", docs.len()),
        ));
    };
    let YamlData::Mapping(map) = &doc.data else {
        return Err(err(
            doc.span.start.line().max(1),
            "a mapping of map_server keys (`image: …`, `resolution: …`, …)",
            "another kind of YAML node",
        ));
    };
    let get = |key: &str| -> Option<&MarkedYaml<'_>> {
        map.iter().find_map(|(k, v)| match &k.data {
            YamlData::Value(Scalar::String(s)) if s.as_ref() == key => Some(v),
            _ => None,
        })
    };
    let line = |n: &MarkedYaml<'_>| n.span.start.line().max(1);
    let describe = |n: &MarkedYaml<'_>| -> String {
        match &n.data {
            YamlData::Value(Scalar::String(s)) => s.to_string(),
            YamlData::Value(Scalar::Integer(i)) => i.to_string(),
            YamlData::Value(Scalar::FloatingPoint(x)) => x.to_string(),
            YamlData::Value(Scalar::Boolean(b)) => b.to_string(),
            YamlData::Value(Scalar::Null) => "null".into(),
            YamlData::Sequence(_) => "a list".into(),
            YamlData::Mapping(_) => "a mapping".into(),
            _ => "another kind of YAML node".into(),
        }
    };
    let number = |n: &MarkedYaml<'_>, what: &str| -> Result<f64, IoError> {
        let v = match &n.data {
            YamlData::Value(Scalar::Integer(i)) => *i as f64,
            YamlData::Value(Scalar::FloatingPoint(x)) => x.into_inner(),
            _ => return Err(err(line(n), &format!("{what}: a number"), &describe(n))),
        };
        if !v.is_finite() {
            return Err(IoError::NonFinite {
                path: path.to_path_buf(),
                line: line(n),
                what: what.to_string(),
                value: v,
            });
        }
        Ok(v)
    };
    let within = |n: &MarkedYaml<'_>, what: &str, lo: f64, hi: f64, unit: &str| {
        let v = number(n, what)?;
        if !(lo..=hi).contains(&v) {
            return Err(IoError::OutOfBounds {
                path: path.to_path_buf(),
                line: line(n),
                what: what.to_string(),
                value: v,
                bound: format!("{lo} … {hi} {unit}"),
            });
        }
        Ok(v)
    };
    let required = |key: &str| {
        get(key).ok_or_else(|| IoError::Parse {
            path: path.to_path_buf(),
            line: 0,
            expected: format!("a `{key}:` entry"),
            found: "none".into(),
        })
    };

    let image_node = required("image")?;
    let image = match &image_node.data {
        YamlData::Value(Scalar::String(s)) if !s.trim().is_empty() => s.to_string(),
        _ => {
            return Err(err(
                line(image_node),
                "image: a file name",
                &describe(image_node),
            ))
        }
    };
    let (rmin, rmax) = RESOLUTION_RANGE;
    let resolution = within(required("resolution")?, "resolution", rmin, rmax, "m/cell")?;
    let origin_node = required("origin")?;
    let parts = match &origin_node.data {
        YamlData::Sequence(v) if v.len() == 3 => v,
        _ => {
            return Err(err(
                line(origin_node),
                "origin: [x, y, yaw]",
                &describe(origin_node),
            ))
        }
    };
    let ox = within(&parts[0], "origin x", -MAX_COORD, MAX_COORD, "m")?;
    let oy = within(&parts[1], "origin y", -MAX_COORD, MAX_COORD, "m")?;
    let yaw = number(&parts[2], "origin yaw")?;
    if yaw != 0.0 {
        return Err(err(
            line(origin_node),
            "origin yaw 0 (rotated maps are not supported)",
            &yaw.to_string(),
        ));
    }
    let negate = match get("negate") {
        None => false,
        Some(n) => match &n.data {
            YamlData::Value(Scalar::Boolean(b)) => *b,
            YamlData::Value(Scalar::Integer(0)) => false,
            YamlData::Value(Scalar::Integer(1)) => true,
            _ => return Err(err(line(n), "negate: 0 or 1", &describe(n))),
        },
    };
    let thresh = |key: &str, default: f64| match get(key) {
        None => Ok(default),
        Some(n) => within(n, key, 0.0, 1.0, "(a probability)"),
    };
    let occupied_thresh = thresh("occupied_thresh", 0.65)?;
    let free_thresh = thresh("free_thresh", 0.196)?;
    // map_server's trinary and scale modes need free < occupied: between them is unknown,
    // and scale divides by their difference.
    if free_thresh >= occupied_thresh {
        let at = get("occupied_thresh")
            .or(get("free_thresh"))
            .map_or(1, line);
        return Err(err(
            at,
            "free_thresh < occupied_thresh",
            &format!("free_thresh {free_thresh} ≥ occupied_thresh {occupied_thresh}"),
        ));
    }
    let scale = match get("mode") {
        None => false,
        Some(n) => match &n.data {
            YamlData::Value(Scalar::String(s)) if s.as_ref() == "trinary" => false,
            YamlData::Value(Scalar::String(s)) if s.as_ref() == "scale" => true,
            _ => {
                return Err(err(
                    line(n),
                    "mode: trinary or scale (raw is not supported)",
                    &describe(n),
                ))
            }
        },
    };
    Ok(MapYaml {
        image,
        resolution,
        origin: Point2::new(ox, oy),
        negate,
        occupied_thresh,
        free_thresh,
        scale,
    })
}

/// One image pixel as map_server sees it: the mean of the colour channels (0…255) and the
/// alpha (255 when the image has none).
type Pixel = (f64, u8);

/// A PGM or PNG map image: (width, height, pixels with the top row first).
fn read_map_image(path: &Path) -> Result<(usize, usize, Vec<Pixel>), IoError> {
    let bytes = crate::text::read_bytes_limited(path, crate::bounds::MAX_TEXT_BYTES)?;
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        return read_png(path, &bytes);
    }
    let (w, h, grey) = read_pgm(path, &bytes)?;
    Ok((w, h, grey.into_iter().map(|v| (v as f64, 255)).collect()))
}

/// Without the `png` feature a PNG map image is an error saying so.
#[cfg(not(feature = "png"))]
fn read_png(path: &Path, _bytes: &[u8]) -> Result<(usize, usize, Vec<Pixel>), IoError> {
    Err(IoError::invalid(
        path,
        "a PNG map image needs slam-io's `png` feature (PGM images are read without it)",
    ))
}

/// A PNG image through the `image` crate, with its size limited to [`MAX_MAP_CELLS`].
#[cfg(feature = "png")]
fn read_png(path: &Path, bytes: &[u8]) -> Result<(usize, usize, Vec<Pixel>), IoError> {
    use image::{ColorType, ImageFormat, ImageReader, Limits};
    let mut reader = ImageReader::with_format(std::io::Cursor::new(bytes), ImageFormat::Png);
    let mut limits = Limits::default();
    // Width and height each at most 2²⁸ and the decoded buffer at most 2²⁸ RGBA16 pixels.
    limits.max_image_width = Some(MAX_MAP_CELLS as u32);
    limits.max_image_height = Some(MAX_MAP_CELLS as u32);
    limits.max_alloc = Some(MAX_MAP_CELLS as u64 * 8);
    reader.limits(limits);
    let img = reader
        .decode()
        .map_err(|e| IoError::invalid(path, format!("cannot decode the PNG map image: {e}")))?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    if w == 0 || h == 0 || w.saturating_mul(h) > MAX_MAP_CELLS {
        return Err(IoError::invalid(
            path,
            format!("image is {w}×{h} pixels, expected 1 … {MAX_MAP_CELLS} pixels"),
        ));
    }
    let grey = matches!(
        img.color(),
        ColorType::L8 | ColorType::L16 | ColorType::La8 | ColorType::La16
    );
    let pix = if grey {
        img.to_luma_alpha8()
            .pixels()
            .map(|p| (p.0[0] as f64, p.0[1]))
            .collect()
    } else {
        img.to_rgba8()
            .pixels()
            .map(|p| {
                let [r, g, b, a] = p.0;
                ((r as f64 + g as f64 + b as f64) / 3.0, a)
            })
            .collect()
    };
    Ok((w, h, pix))
}

/// A PGM image (P5 binary or P2 ASCII, maxval ≤ 255): (width, height, pixels scaled to
/// 0…255, top row first).
fn read_pgm(path: &Path, bytes: &[u8]) -> Result<(usize, usize, Vec<u8>), IoError> {
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
        .filter(|&n| n <= MAX_MAP_CELLS)
        .ok_or_else(|| bad(&format!("an image of at most {MAX_MAP_CELLS} pixels")))?;
    match magic {
        "P5" => {
            let data = &bytes[(pos + 1).min(bytes.len())..];
            exact_pixels(path, data.len(), (w, h))?;
            Ok((w, h, data.iter().map(|&v| scale(v as usize)).collect()))
        }
        "P2" => {
            let rest = String::from_utf8_lossy(&bytes[pos..]);
            let vals: Result<Vec<u8>, _> = rest
                .split_whitespace()
                .take(n + 1)
                .map(|t| t.parse::<usize>().map(scale))
                .collect();
            let vals = vals.map_err(|_| bad("pixel values"))?;
            exact_pixels(path, vals.len(), (w, h))?;
            Ok((w, h, vals))
        }
        _ => Err(bad("a P5 or P2 PGM image, or a PNG image")),
    }
}

/// The image data must hold exactly width × height pixels: fewer is a truncated image,
/// more (or rows a pixel short, which shear the map) an image of another size.
fn exact_pixels(path: &Path, found: usize, (w, h): (usize, usize)) -> Result<(), IoError> {
    let n = w * h;
    if found == n {
        return Ok(());
    }
    let hint = if h > 1 && found % h == 0 && found / h != w {
        format!(" (rows of {} pixels?)", found / h)
    } else {
        String::new()
    };
    Err(IoError::invalid(
        path,
        format!(
            "image data of {}{found} pixels{hint}, the header says {w}×{h} = {n}",
            if found > n { "at least " } else { "" }
        ),
    ))
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
            ("image m.pgm\n", "a mapping of map_server keys"),
            ("image: [m.pgm\n", "m.yaml:"),
            (
                "image: m.pgm\nimage: n.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n",
                "m.yaml:",
            ),
            (
                "image: m.pgm\nresolution: 1e308\norigin: [0, 0, 0]\n",
                "m.yaml:2: resolution = 1e308 is out of bounds",
            ),
            (
                "image: m.pgm\nresolution: 0.1\norigin: [2e6, 0, 0]\n",
                "origin x = 2000000.0 is out of bounds",
            ),
            (
                "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmode: raw\n",
                "m.yaml:4: expected mode: trinary or scale",
            ),
            (
                "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nfree_thresh: 2\n",
                "free_thresh = 2.0 is out of bounds",
            ),
            (
                "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 7\n",
                "negate: 0 or 1",
            ),
            (
                format!("image: m.pgm\nx: {}\n", "[".repeat(100)).as_str(),
                "nested",
            ),
            ("image: m.pgm\n", "resolution"),
            (
                "image: m.pgm\nresolution: x\norigin: [0, 0, 0]\n",
                "resolution: a number",
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
        let e = read_ros_map(&y).unwrap_err().to_string();
        assert!(
            e.contains("image data of 2 pixels, the header says 4×4 = 16"),
            "{e}"
        );
        // Rows one pixel short (a sheared map): 3 rows of 3 pixels under a 4×3 header, in
        // both PGM flavours; and one pixel too many.
        std::fs::write(
            d.join("m.pgm"),
            b"P5\n4 3\n255\n\x00\x00\x00\x00\x00\x00\x00\x00\x00",
        )
        .unwrap();
        let e = read_ros_map(&y).unwrap_err().to_string();
        assert!(
            e.contains("9 pixels (rows of 3 pixels?), the header says 4×3 = 12"),
            "{e}"
        );
        std::fs::write(d.join("m.pgm"), b"P2\n4 3\n255\n0 0 0\n0 0 0\n0 0 0\n").unwrap();
        let e = read_ros_map(&y).unwrap_err().to_string();
        assert!(e.contains("(rows of 3 pixels?)"), "{e}");
        std::fs::write(d.join("m.pgm"), b"P5\n2 1\n255\n\x00\x00\x00").unwrap();
        let e = read_ros_map(&y).unwrap_err().to_string();
        assert!(
            e.contains("image data of at least 3 pixels, the header says 2×1 = 2"),
            "{e}"
        );
        // Thresholds in the wrong order, named with the line of occupied_thresh.
        std::fs::write(
            &y,
            "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\noccupied_thresh: 0.1\nfree_thresh: 0.5\n",
        )
        .unwrap();
        let e = read_ros_map(&y).unwrap_err().to_string();
        assert!(
            e.contains("m.yaml:4") && e.contains("free_thresh 0.5 ≥ occupied_thresh 0.1"),
            "{e}"
        );
        std::fs::write(&y, "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n").unwrap();
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

    #[test]
    #[cfg(feature = "png")]
    fn yaml_comments_list_styles_and_png_images() {
        let d = tmp("png");
        // Grey PNG, 3×2, top row first: black, mid-grey, white / white, 205-grey, black.
        let grey = image::GrayImage::from_raw(3, 2, vec![0, 128, 255, 255, 205, 0]).unwrap();
        grey.save(d.join("g.png")).unwrap();
        let y = d.join("map.yaml");
        // Inline comments, quoted name, block-style origin list, a boolean negate.
        std::fs::write(
            &y,
            "# map_server map\nimage: \"g.png\"   # the picture\nresolution: 0.5 # m/cell\n\
             origin:\n  - -1.0\n  - 2\n  - 0.0\nnegate: false\noccupied_thresh: 0.65\n\
             free_thresh: 0.196 # default\n",
        )
        .unwrap();
        let m = read_ros_map(&y).unwrap();
        assert_eq!((m.width, m.height, m.resolution), (3, 2, 0.5));
        assert_eq!(m.origin, Point2::new(-1.0, 2.0));
        // p = (255 − v)/255: 255 → 0 free; 205 → 0.196 unknown; 128 → 0.498 unknown; 0 → 1
        // occupied. Bottom row (image row 1) first in the grid.
        assert_eq!(m.cells, vec![0, -1, 100, 100, -1, 0]);
        // Flow-style origin and negate 1: p = v/255.
        std::fs::write(
            &y,
            "image: g.png\nresolution: 0.5\norigin: [ -1.0, 2, 0 ]  # x, y, yaw\nnegate: 1\n",
        )
        .unwrap();
        assert_eq!(
            read_ros_map(&y).unwrap().cells,
            vec![100, 100, 0, 0, -1, 100]
        );
        // RGBA PNG in scale mode: mean of r, g, b; a transparent pixel is unknown.
        let rgba = image::RgbaImage::from_raw(
            2,
            1,
            vec![
                255, 0, 0, 255, /* mean 85 */ 120, 130, 140,
                0, /* mean 130, transparent */
            ],
        )
        .unwrap();
        rgba.save(d.join("c.png")).unwrap();
        std::fs::write(
            &y,
            "image: c.png\nresolution: 1\norigin: [0, 0, 0]\nmode: scale\n\
             occupied_thresh: 0.9\nfree_thresh: 0.1\n",
        )
        .unwrap();
        // p = (255 − 85)/255 = 0.667 → 1 + ⌊98·(0.667 − 0.1)/0.8⌋ = 70.
        assert_eq!(read_ros_map(&y).unwrap().cells, vec![70, -1]);
        // A truncated PNG is an error naming the image.
        let bytes = std::fs::read(d.join("c.png")).unwrap();
        std::fs::write(d.join("c.png"), &bytes[..bytes.len() / 2]).unwrap();
        let e = read_ros_map(&y).unwrap_err().to_string();
        assert!(e.contains("c.png") && e.contains("PNG"), "{e}");
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn deep_or_aliased_yaml_is_an_error_not_a_crash() {
        // Each would overflow the stack or exhaust memory if handed to the tree builder.
        let d = tmp("deep");
        let y = d.join("m.yaml");
        let laughs: String = (1..10)
            .map(|i| {
                format!(
                    "l{i}: &l{i} [{}]\n",
                    vec![format!("*l{}", i - 1); 9].join(",")
                )
            })
            .collect();
        for (text, want) in [
            (
                format!("image: m.pgm\nx:\n{}1\n", "- ".repeat(200_000)),
                "m.yaml:3",
            ),
            (
                format!("image: m.pgm\nx:\n{}1\n", "? ".repeat(200_000)),
                "nested",
            ),
            (
                format!("image: m.pgm\nx: {}\n", "[".repeat(200_000)),
                "m.yaml:2",
            ),
            (
                format!("image: m.pgm\nx: {}\n", "{a: ".repeat(200_000)),
                "m.yaml:2",
            ),
            (format!("l0: &l0 [1]\n{laughs}"), "m.yaml"),
        ] {
            std::fs::write(&y, &text).unwrap();
            let e = read_ros_map(&y).unwrap_err().to_string();
            assert!(e.contains(want), "{} → {e}", &text[..40]);
        }
        std::fs::remove_dir_all(&d).ok();
    }
}
