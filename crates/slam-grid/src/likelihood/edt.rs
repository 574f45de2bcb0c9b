//! Exact Euclidean distance transform in linear time (Felzenszwalb & Huttenlocher,
//! "Distance Transforms of Sampled Functions", Theory of Computing 8, 2012, §2–3).
//!
//! The 1-D transform D_f(q) = min_p ((q − p)² + f(p)) is the lower envelope of parabolas
//! rooted at the sample points (Algorithm 1 of the paper, `DT(f)`); the 2-D squared
//! Euclidean transform is the 1-D transform along columns, then along rows (§3).

/// Scratch buffers for [`edt_1d`], reused across calls to avoid allocation.
#[derive(Debug, Default)]
pub(crate) struct EdtScratch {
    v: Vec<usize>,
    z: Vec<f64>,
    f: Vec<f64>,
    d: Vec<f64>,
    a: Vec<usize>,
}

/// 1-D transform of `f` (∞ entries are "no site") into `d`: d[q] = min_p ((q − p)² + f[p]),
/// or ∞ when every f[p] is infinite; `arg[q]` receives the minimising p (the feature
/// transform; 0 when there is none).
pub(crate) fn edt_1d(
    f: &[f64],
    d: &mut [f64],
    arg: &mut [usize],
    scratch_v: &mut Vec<usize>,
    scratch_z: &mut Vec<f64>,
) {
    let v = scratch_v;
    let z = scratch_z;
    v.clear();
    z.clear();
    for (q, &fq) in f.iter().enumerate() {
        if !fq.is_finite() {
            continue;
        }
        let qf = q as f64;
        loop {
            match v.last() {
                None => {
                    v.push(q);
                    z.push(f64::NEG_INFINITY);
                    break;
                }
                Some(&p) => {
                    let pf = p as f64;
                    // Intersection of the parabolas rooted at p and q (F&H eq. in Alg. 1).
                    let s = ((fq + qf * qf) - (f[p] + pf * pf)) / (2.0 * qf - 2.0 * pf);
                    if s <= z[z.len() - 1] {
                        v.pop();
                        z.pop();
                    } else {
                        v.push(q);
                        z.push(s);
                        break;
                    }
                }
            }
        }
    }
    if v.is_empty() {
        d.iter_mut().for_each(|x| *x = f64::INFINITY);
        arg.iter_mut().for_each(|a| *a = 0);
        return;
    }
    let mut k = 0;
    for (q, (dq, aq)) in d.iter_mut().zip(arg.iter_mut()).enumerate() {
        let qf = q as f64;
        while k + 1 < v.len() && z[k + 1] < qf {
            k += 1;
        }
        let p = v[k];
        let dp = qf - p as f64;
        *dq = dp * dp + f[p];
        *aq = p;
    }
}

/// Squared Euclidean distance, in cells², from every cell of a `w × h` row-major raster to
/// the nearest cell where `obstacle` is true (∞ when there is none), and the row-major index
/// of that nearest obstacle cell (the feature transform; meaningless where the distance is
/// ∞).
pub(crate) fn edt_2d(
    obstacle: &[bool],
    w: usize,
    h: usize,
    scratch: &mut EdtScratch,
) -> (Vec<f64>, Vec<u32>) {
    debug_assert_eq!(obstacle.len(), w * h);
    let (mut out, col_arg) = column_pass(obstacle, w, h);
    let mut site = vec![0u32; w * h];
    let EdtScratch { v, z, f, d, a } = scratch;
    f.resize(w, 0.0);
    d.resize(w, 0.0);
    a.resize(w, 0);
    // Rows: the nearest site of cell (x, y) is in column p = arg, at that column's row.
    for y in 0..h {
        let row = &mut out[y * w..(y + 1) * w];
        f[..w].copy_from_slice(row);
        edt_1d(&f[..w], &mut d[..w], &mut a[..w], v, z);
        row.copy_from_slice(&d[..w]);
        for x in 0..w {
            let p = a[x];
            site[y * w + x] = col_arg[y * w + p] * w as u32 + p as u32;
        }
    }
    (out, site)
}

/// The column pass of [`edt_2d`]: for every cell, the squared distance (cells²) to the
/// nearest obstacle cell in its column and that cell's row (∞ and row 0 in a column
/// without one). Because the sites are binary (f = 0 on an obstacle, ∞ elsewhere), this is
/// [`edt_1d`] of each column computed by two scans (forward for the nearest obstacle at or
/// above, backward for the nearest at or below; Meijster, Roerdink and Hesselink 2002,
/// phase 1), row by row so that memory is read in order. Equal to `edt_1d` value for value
/// and in its choice on a tie: the envelope's breakpoints are the midpoints (p + q)/2 and a
/// cell on one keeps the lower root, so the obstacle above (the smaller row) wins.
fn column_pass(obstacle: &[bool], w: usize, h: usize) -> (Vec<f64>, Vec<u32>) {
    const NONE: u32 = u32::MAX;
    // Forward: the nearest obstacle row at or above, kept per cell in `arg` (which the
    // backward scan then overwrites with the nearer of the two).
    let mut arg = vec![NONE; w * h];
    let mut above_row = vec![NONE; w];
    for y in 0..h {
        let row = &obstacle[y * w..(y + 1) * w];
        for ((last, cell), &o) in above_row
            .iter_mut()
            .zip(&mut arg[y * w..(y + 1) * w])
            .zip(row)
        {
            if o {
                *last = y as u32;
            }
            *cell = *last;
        }
    }
    // Backward: the nearest at or below, and the nearer of the two (above on a tie).
    let mut out = vec![f64::INFINITY; w * h];
    let mut below_row = vec![NONE; w];
    for y in (0..h).rev() {
        let r = y * w..(y + 1) * w;
        for ((next, &o), (d, a)) in below_row
            .iter_mut()
            .zip(&obstacle[r.clone()])
            .zip(out[r.clone()].iter_mut().zip(&mut arg[r]))
        {
            if o {
                *next = y as u32;
            }
            let yu = y as u32;
            let p = match (*a, *next) {
                (NONE, NONE) => {
                    *a = 0;
                    continue;
                }
                (NONE, down) => down,
                (up, NONE) => up,
                (up, down) => {
                    if yu - up <= down - yu {
                        up
                    } else {
                        down
                    }
                }
            };
            let dp = y as f64 - p as f64;
            *d = dp * dp;
            *a = p;
        }
    }
    (out, arg)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The two-scan column pass against Felzenszwalb and Huttenlocher's envelope on every
    /// column: the same distances to the bit and the same row chosen on ties (rasters
    /// with evenly spaced obstacles make ties on every other cell).
    #[test]
    fn column_pass_is_the_envelope_transform_of_each_column() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(12);
        let (mut v, mut z) = (Vec::new(), Vec::new());
        for trial in 0..200 {
            let w = rng.random_range(1..30);
            let h = rng.random_range(1..60);
            let obst: Vec<bool> = if trial % 4 == 3 {
                let step = rng.random_range(2..6);
                (0..w * h).map(|i| (i / w) % step == 0).collect()
            } else {
                let density = [0.0, 0.05, 0.3][trial % 4 % 3];
                (0..w * h).map(|_| rng.random_bool(density)).collect()
            };
            let (d, arg) = column_pass(&obst, w, h);
            for x in 0..w {
                let f: Vec<f64> = (0..h)
                    .map(|y| if obst[y * w + x] { 0.0 } else { f64::INFINITY })
                    .collect();
                let (mut dd, mut aa) = (vec![0.0; h], vec![0usize; h]);
                edt_1d(&f, &mut dd, &mut aa, &mut v, &mut z);
                for y in 0..h {
                    assert_eq!(d[y * w + x].to_bits(), dd[y].to_bits(), "({x},{y}) {w}x{h}");
                    assert_eq!(arg[y * w + x] as usize, aa[y], "({x},{y}) {w}x{h}");
                }
            }
        }
    }

    #[test]
    fn matches_brute_force_on_random_rasters() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(11);
        let mut scratch = EdtScratch::default();
        for trial in 0..60 {
            let w = rng.random_range(1..40);
            let h = rng.random_range(1..40);
            let density = [0.0, 0.002, 0.02, 0.2, 0.9][trial % 5];
            let obst: Vec<bool> = (0..w * h).map(|_| rng.random_bool(density)).collect();
            let (got, site) = edt_2d(&obst, w, h, &mut scratch);
            let sites: Vec<(usize, usize)> = (0..w * h)
                .filter(|&i| obst[i])
                .map(|i| (i % w, i / w))
                .collect();
            for y in 0..h {
                for x in 0..w {
                    let brute = sites
                        .iter()
                        .map(|&(sx, sy)| {
                            let dx = sx as f64 - x as f64;
                            let dy = sy as f64 - y as f64;
                            dx * dx + dy * dy
                        })
                        .fold(f64::INFINITY, f64::min);
                    let g = got[y * w + x];
                    assert!(
                        (g == brute) || (g - brute).abs() < 1e-9,
                        "cell ({x},{y}) of {w}x{h}: EDT {g}, brute force {brute}"
                    );
                    if brute.is_finite() {
                        // The feature transform names an obstacle at that distance.
                        let s = site[y * w + x] as usize;
                        assert!(obst[s]);
                        let (sx, sy) = ((s % w) as f64, (s / w) as f64);
                        let ds = (sx - x as f64).powi(2) + (sy - y as f64).powi(2);
                        assert!((ds - brute).abs() < 1e-9, "site at {ds}, nearest {brute}");
                    }
                }
            }
        }
    }
}
