//! Loop closure of the laser front end: the search of finished submaps around the pose the
//! graph predicts, in a window sized from the graph distance between the two places
//! ([`loop_window`]), under a per-keyframe budget and a per-submap sampling of the
//! candidacies ([`Sampler`]); the checks a match must pass (unique,
//! not flat); the group of candidates and its consistency test
//! ([`consistency::dominant_group`]); the end-of-run flush of that group.

use super::consistency;
use super::{covariance, invert, Constraint, LaserGraphConfig, LaserGraphSlam, LoopMap};
use crate::error::GraphError;
use slam_grid::{BranchBoundMatcher, MaxPyramid, OccupancyGrid, RangeData};
use slam_models::{LaserScan, Pose2};
use std::cmp::Reverse;

impl LaserGraphSlam {
    /// Once the pending group of candidate closures is complete (`loop-group-span`
    /// keyframes since its first candidate, or `loop-group-gap` keyframes without one),
    /// or at once when `now`), checks it for mutual consistency
    /// ([`consistency::dominant_group`]) and adds the dominant cluster's closures to the
    /// graph; true when some were added.
    pub(super) fn settle_group(&mut self, k: usize, now: bool) -> bool {
        let c = &self.config;
        let (first, last) = self.pending_span;
        if self.pending.is_empty()
            || (!now && k < first + c.loop_group_span && k < last + c.loop_group_gap)
        {
            return false;
        }
        let hyps: Vec<consistency::Hypothesis> = self
            .pending
            .iter()
            .map(|p| {
                let (a, b) = (&self.keyframes[p.from], &self.keyframes[p.to]);
                consistency::Hypothesis {
                    z: p.z,
                    covariance: invert(&p.information),
                    a: a.local,
                    b: b.local,
                    a_path: a.path,
                    b_path: b.path,
                }
            })
            .collect();
        let test = consistency::GroupTest {
            drift: c.loop_group_drift,
            min_size: c.loop_group_min_size,
            min_ratio: c.loop_group_min_ratio,
        };
        let decision = consistency::dominant_group(&hyps, &test);
        let pending = std::mem::take(&mut self.pending);
        self.stats.loop_groups += 1;
        self.stats.loop_inconsistent += pending.len() - decision.accepted.len();
        self.stats.loop_closures += decision.accepted.len();
        for &i in &decision.accepted {
            self.constraints.push(pending[i]);
        }
        !decision.accepted.is_empty()
    }

    /// True when the response of `scan` on `grid` around `pose` is flat along one
    /// direction: the translational block of its sampled covariance
    /// ([`covariance::response_covariance`]) has σ_max / σ_min above `loop-max-anisotropy`.
    fn flat_match(&self, grid: &OccupancyGrid, scan: &RangeData, pose: &Pose2) -> bool {
        // With the matcher's own covariance configured, a fixed window samples the surface.
        let sampling = covariance::ResponseSampling::configured(self.config.match_covariance)
            .unwrap_or(covariance::ResponseSampling {
                linear_window: 0.3,
                angular_window: 0.03,
                temperature: 10.0,
            });
        let Some(cov) = covariance::response_covariance(grid, scan, pose, &sampling) else {
            return true;
        };
        covariance::xy_anisotropy(&cov).0 > self.config.loop_max_anisotropy
    }

    /// Searches finished submaps for loop closures of keyframe `k` and adds the matches to
    /// the pending group (`settle_group` decides which enter the graph); true when one was
    /// found.
    pub(super) fn search_loops(&mut self, k: usize) -> Result<bool, GraphError> {
        let distances = self.graph_distances(k, window_reach(&self.config));
        let c = &self.config;
        let kf = &self.keyframes[k];
        let position = kf.global.translation();
        // Candidates: finished submaps old enough whose nearest keyframe lies within the
        // submap's search window (plus half the matching range) of the predicted position.
        let mut candidates: Vec<(f64, usize, f64, f64)> = Vec::new();
        for (s, submap) in self.submaps.iter().enumerate() {
            let Some(&last) = submap.keyframes.last() else {
                continue;
            };
            if !submap.finished || last + c.loop_min_scan_gap > k {
                continue;
            }
            let nearest = submap
                .keyframes
                .iter()
                .map(|&j| (self.keyframes[j].global.translation() - position).norm())
                .fold(f64::INFINITY, f64::min);
            // The window grows with the graph distance between the submap and keyframe k:
            // the uncertainty of their relative pose before this closure (metres of the
            // scan-matching chain, closures counting nothing).
            let d = submap
                .keyframes
                .iter()
                .map(|&j| distances[j])
                .fold(f64::INFINITY, f64::min);
            let (radius, angle) = loop_window(c, d);
            // The scan overlaps the submap when some of its keyframes is within the
            // matching range (plus the search radius) of the predicted position.
            if nearest <= radius + 0.5 * c.match_max_range {
                candidates.push((nearest, s, radius, angle));
            }
        }
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // The per-keyframe budget: at most `loop-max-candidates` submaps, nearest first,
        // each in a fraction `loop-sampling-ratio` of its candidacies ([`Sampler`]),
        // each searched first in the narrow window (the window capped at `loop-wide-radius`
        // and `loop-wide-angle`); a search in the whole window, when it is wider and the
        // narrow one found nothing acceptable, at most one per keyframe and, after one that
        // found nothing, not again for `loop-wide-interval` keyframes.
        let mut wide_left = match self.last_wide_search {
            Some(w) if k < w + c.loop_wide_interval => 0,
            _ => 1,
        };
        let mut found = false;
        for &(_, s, radius, angle) in candidates.iter().take(c.loop_max_candidates) {
            let ratio = self.config.loop_sampling_ratio;
            if !self.submaps[s].sampler.pulse(ratio) {
                continue;
            }
            let c = &self.config;
            let narrow = (radius.min(c.loop_wide_radius), angle.min(c.loop_wide_angle));
            let mut closure = self.loop_candidate(k, s, narrow.0, narrow.1)?;
            if closure.is_none() && (radius > narrow.0 || angle > narrow.1) && wide_left > 0 {
                wide_left -= 1;
                self.stats.loop_wide_searches += 1;
                closure = self.loop_candidate(k, s, radius, angle)?;
                // A wide search that found a candidate does not use up the budget: the
                // next keyframes may search wide again and so give the group test the
                // second and further candidates it needs (they would otherwise come one
                // per `loop-wide-interval` keyframes, too sparse for `loop-group-gap`).
                if closure.is_none() {
                    self.last_wide_search = Some(k);
                }
            }
            let Some(closure) = closure else {
                continue;
            };
            if self.pending.is_empty() {
                self.pending_span.0 = k;
            }
            self.pending_span.1 = k;
            self.pending.push(closure);
            found = true;
        }
        Ok(found)
    }

    /// Searches finished submap `s` for keyframe `k` within `radius` metres and `angle`
    /// radians of the pose the graph predicts ([`BranchBoundMatcher`] on its pyramid) and
    /// returns the closure if the match passes the checks: score at least `loop-min-score`,
    /// unique (`loop-ambiguity-ratio`), not flat (`loop-max-anisotropy`).
    fn loop_candidate(
        &mut self,
        k: usize,
        s: usize,
        radius: f64,
        angle: f64,
    ) -> Result<Option<Constraint>, GraphError> {
        let c = &self.config;
        let matcher = BranchBoundMatcher {
            linear_window: radius,
            angular_window: angle,
            angular_step: 0.0,
            depth: c.loop_depth,
            min_score: c.loop_min_score,
            min_points: c.local_matcher.correlative.min_points,
        };
        let anchor = self.submaps[s].keyframes[0];
        let (a_local, a_global) = (self.keyframes[anchor].local, self.keyframes[anchor].global);
        // Keyframe k in the submap's (local) frame, as the current graph predicts it.
        let predicted = a_local.compose(&a_global.between(&self.keyframes[k].global));
        if !self.cache_loop_map(s)? {
            return Ok(None);
        }
        self.stats.loop_searches += 1;
        let loop_map = self.loop_maps.back().expect("cached above");
        let pyramid = &loop_map.pyramid;
        let Some(scan) = self
            .newest_scan
            .as_ref()
            .filter(|_| k + 1 == self.keyframes.len())
        else {
            return Ok(None);
        };
        let hit = match matcher.match_in(pyramid, scan, &predicted) {
            Ok(Some(m)) => m,
            Ok(None) | Err(_) => return Ok(None),
        };
        if self.config.loop_ambiguity_ratio < 1.0
            && self.ambiguous(pyramid, scan, &hit.pose, hit.score)
        {
            self.stats.loop_ambiguous += 1;
            return Ok(None);
        }
        // Sub-cell refinement on the submap itself; kept only if it stays close.
        if self.loop_maps.back().is_some_and(|m| m.grid.is_none()) {
            let grid = self.loop_grid(s)?;
            if let Some(m) = self.loop_maps.back_mut() {
                m.grid = Some(grid);
            }
        }
        let (Some(grid), Some(scan)) = (
            self.loop_maps.back().and_then(|m| m.grid.as_ref()),
            self.newest_scan.as_ref(),
        ) else {
            return Ok(None);
        };
        let m = self.refine_near(grid, scan, hit);
        if self.flat_match(grid, scan, &m.pose) {
            self.stats.loop_flat += 1;
            return Ok(None);
        }
        // The edge starts at the submap's keyframe nearest to the match: the submap is
        // exact relative to its own keyframes' local poses only up to its internal
        // drift, which grows with the distance along it.
        let from = self.submaps[s]
            .keyframes
            .iter()
            .copied()
            .min_by(|&a, &b| {
                let da = self.keyframes[a].local.distance(&m.pose);
                let db = self.keyframes[b].local.distance(&m.pose);
                da.total_cmp(&db).then(a.cmp(&b))
            })
            .unwrap_or(anchor);
        let from_local = self.keyframes[from].local;
        let z = from_local.between(&m.pose);
        // The matcher's own covariance: on the office the response's made the
        // closures slightly worse (docs/results/graph.md).
        let information = self.match_information(&m.covariance, from_local.theta);
        Ok(Some(Constraint {
            from,
            to: k,
            z,
            information,
            loop_closure: true,
        }))
    }

    /// Ends the run: the pending group of candidate closures (collected over fewer than
    /// `loop-group-span` keyframes when the data ended) is checked and its consistent
    /// closures enter the graph, which is then optimised, instead of being dropped.
    /// Records may still follow (the group is simply settled early).
    pub fn finish_run(&mut self) -> Result<(), GraphError> {
        let Some(k) = self.keyframes.len().checked_sub(1) else {
            return Ok(());
        };
        if self.settle_group(k, true) {
            self.optimize_keyframes()?;
        }
        Ok(())
    }

    /// The graph distance of every keyframe from keyframe `k`, metres (Dijkstra over the
    /// keyframe graph): the edge between consecutive keyframes (scan matching, or odometry
    /// where the match failed) costs the path between them, an accepted loop closure
    /// nothing. The shortest such path is the chain of local matches whose drift the
    /// relative pose of the two keyframes still carries: the path since the closures that
    /// last joined their neighbourhoods. Candidates still pending are not counted: they are
    /// not in the graph, so the pose the graph predicts has not been corrected by them.
    /// The search stops at `reach` metres, beyond which the window is at its caps anyway
    /// ([`loop_window`]); keyframes farther away are at infinity.
    fn graph_distances(&self, k: usize, reach: f64) -> Vec<f64> {
        let n = self.keyframes.len();
        let mut closures: Vec<Vec<usize>> = vec![Vec::new(); n];
        for c in self.constraints.iter().filter(|c| c.loop_closure) {
            if c.from < n && c.to < n {
                closures[c.from].push(c.to);
                closures[c.to].push(c.from);
            }
        }
        let mut distance = vec![f64::INFINITY; n];
        let mut heap = std::collections::BinaryHeap::new();
        if k < n {
            distance[k] = 0.0;
            heap.push(Reverse(Ordered(0.0, k)));
        }
        while let Some(Reverse(Ordered(d, i))) = heap.pop() {
            if d > distance[i] || d > reach {
                continue;
            }
            let path = self.keyframes[i].path;
            let chain = [i.checked_sub(1), Some(i + 1).filter(|&j| j < n)];
            let chain = chain
                .into_iter()
                .flatten()
                .map(|j| (j, (self.keyframes[j].path - path).abs()));
            for (j, w) in chain.chain(closures[i].iter().map(|&j| (j, 0.0))) {
                let e = d + w;
                if e < distance[j] {
                    distance[j] = e;
                    heap.push(Reverse(Ordered(e, j)));
                }
            }
        }
        distance
    }

    /// True when some pose 0.25 m, 0.5 m or 1 m away from `best` (8 directions, each
    /// followed by a small branch-and-bound search of ±0.1 m, ±0.2 m, ±0.2 m and
    /// ±0.05 rad) scores at least
    /// `loop-ambiguity-ratio` × `score`: the match is not unique. The searches start
    /// from blocks of 8 × 8 cells (pyramid level 3): fewer roots to score than blocks of
    /// 4 × 4, and the answer is the same for any depth (the search is exact, and only
    /// whether a pose reaches the bar is asked).
    fn ambiguous(&self, pyramid: &MaxPyramid, scan: &RangeData, best: &Pose2, score: f64) -> bool {
        let bar = self.config.loop_ambiguity_ratio * score;
        let local = BranchBoundMatcher {
            linear_window: 0.2,
            angular_window: 0.05,
            angular_step: 0.0,
            depth: 4.min(pyramid.depth()),
            min_score: bar.clamp(0.0, 1.0),
            min_points: 1,
        };
        for (d, window) in [(0.25, 0.1), (0.5, 0.2), (1.0, 0.2)] {
            let local = BranchBoundMatcher {
                linear_window: window,
                ..local
            };
            for k in 0..8 {
                let a = k as f64 * std::f64::consts::FRAC_PI_4;
                let shifted = Pose2::new(best.x + d * a.cos(), best.y + d * a.sin(), best.theta);
                if let Ok(Some(_)) = local.match_in(pyramid, scan, &shifted) {
                    return true;
                }
            }
        }
        false
    }

    /// Puts finished submap `s`'s loop-closure pyramid (and grid) at the back of the
    /// cache, rebuilding them from its keyframes' scans if needed (the least recently used
    /// entries are dropped beyond `loop-pyramid-cache` entries or
    /// `loop-pyramid-cache-bytes`, and the grids of all but the
    /// `loop-max-candidates` most recently used, the submaps one keyframe searches: the
    /// search reads only the pyramid, and a match on a submap whose grid was dropped
    /// rebuilds it); false for an empty submap.
    fn cache_loop_map(&mut self, s: usize) -> Result<bool, GraphError> {
        if let Some(pos) = self.loop_maps.iter().position(|m| m.submap == s) {
            let entry = self.loop_maps.remove(pos).expect("position is valid");
            self.loop_maps.push_back(entry);
        } else {
            // Room first, so that the new entry is not built alongside a full cache: under
            // the count, and under the byte budget with room for one more of the mean size.
            let mut bytes: usize = self
                .loop_maps
                .iter()
                .map(|m| m.pyramid.memory_bytes())
                .sum();
            while let Some(mean) = bytes.checked_div(self.loop_maps.len()) {
                let full = self.loop_maps.len() >= self.config.loop_pyramid_cache
                    || bytes + mean > self.config.loop_pyramid_cache_bytes;
                if !full {
                    break;
                }
                if let Some(dropped) = self.loop_maps.pop_front() {
                    bytes -= dropped.pyramid.memory_bytes();
                }
            }
            let mut grid = self.loop_grid(s)?;
            let Some(pyramid) = loop_pyramid(&grid, self.config.loop_depth)? else {
                return Ok(false);
            };
            // The search reads the pyramid; the grid's field is read again only around a
            // match.
            grid.drop_field_cache();
            self.loop_maps.push_back(LoopMap {
                submap: s,
                grid: Some(grid),
                pyramid,
            });
        }
        let keep = self.config.loop_max_candidates.max(1);
        for m in self.loop_maps.iter_mut().rev().skip(keep) {
            m.grid = None;
        }
        Ok(true)
    }

    /// A branch-and-bound `hit` of `scan` on `grid` refined by the local matcher's
    /// Gauss-Newton step (sub-cell), the refinement kept only if it stays within two cells
    /// of the hit (else the hit itself).
    pub(super) fn refine_near(
        &self,
        grid: &OccupancyGrid,
        scan: &RangeData,
        hit: slam_grid::MatchResult,
    ) -> slam_grid::MatchResult {
        match self
            .config
            .local_matcher
            .refine
            .match_prepared(grid, scan, &hit.pose)
        {
            Ok(f) if f.pose.distance(&hit.pose) <= 2.0 * self.config.resolution => f,
            _ => hit,
        }
    }

    /// A scan checked and classified for the submaps ([`RangeData`] under the configured
    /// sensor model), its end points beyond `match-max-range` left out of matching.
    pub(super) fn prepare(&self, scan: &LaserScan) -> Result<RangeData, GraphError> {
        Ok(RangeData::with_limits(
            scan,
            &self.config.sensor_model,
            0.0,
            self.config.match_max_range,
        )?)
    }

    /// Finished submap `s`'s grid, rebuilt from its keyframes' scans at their local poses
    /// (the same insertions in the same order as while it was active, so the same grid).
    fn loop_grid(&self, s: usize) -> Result<OccupancyGrid, GraphError> {
        let mut grid = self.empty_submap_grid()?;
        for &k in &self.submaps[s].keyframes {
            let kf = &self.keyframes[k];
            grid.try_integrate_prepared(&kf.local, &self.prepare(&kf.scan)?)?;
        }
        Ok(grid)
    }
}

/// A deterministic sampler of a fixed ratio (Cartographer's `common::FixedRatioSampler`):
/// of the `pulses` so far, `samples` returned true.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Sampler {
    pulses: u64,
    samples: u64,
}

impl Sampler {
    /// Counts one pulse and returns true when the fraction of pulses sampled so far is
    /// below `ratio` (then counting this one as sampled): the first pulse is sampled, and
    /// after n pulses ⌈ratio·n⌉ have been; `ratio` ≥ 1 samples every pulse.
    pub(super) fn pulse(&mut self, ratio: f64) -> bool {
        self.pulses += 1;
        if (self.samples as f64) < ratio * self.pulses as f64 {
            self.samples += 1;
            return true;
        }
        false
    }
}

/// The loop-closure search window (radius in metres, rotation half-width in radians) for
/// a relative pose carried by `d` metres of scan-matching chain: `loop-radius` +
/// `loop-radius-growth`·d and `loop-angle` + `loop-angle-growth`·d (a 3σ bound on a drift
/// whose standard deviation grows linearly with the path), capped at `loop-max-radius`
/// and `loop-max-angle`.
fn loop_window(c: &LaserGraphConfig, d: f64) -> (f64, f64) {
    let radius = (c.loop_radius + c.loop_radius_growth * d).min(c.loop_max_radius);
    let angle = (c.loop_angle + c.loop_angle_growth * d).min(c.loop_max_angle);
    (radius, angle)
}

/// The graph distance beyond which [`loop_window`] is at both caps: the radius reaches
/// `loop-max-radius` after (max − `loop-radius`) / growth metres, the angle likewise (0 when
/// a window does not grow or starts at its cap; infinite never, as growth > 0 is finite).
fn window_reach(c: &LaserGraphConfig) -> f64 {
    let at_cap = |start: f64, growth: f64, max: f64| {
        if growth > 0.0 {
            ((max - start) / growth).max(0.0)
        } else {
            0.0
        }
    };
    at_cap(c.loop_radius, c.loop_radius_growth, c.loop_max_radius).max(at_cap(
        c.loop_angle,
        c.loop_angle_growth,
        c.loop_max_angle,
    ))
}

/// A (distance, keyframe) pair ordered by the distance (total order), for the Dijkstra heap.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Ordered(f64, usize);

impl Eq for Ordered {}

impl PartialOrd for Ordered {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Ordered {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0).then(self.1.cmp(&other.1))
    }
}

/// The loop-closure pyramid of a submap grid over the cells where its likelihood field
/// is not the far value: the obstacles' bounding box grown by the field's reach
/// (`max-distance`, plus two cells for the sub-cell hit positions). Outside it the
/// pyramid reads the far value, as the field there is, so the search is the same as
/// over every covered cell, on a smaller pyramid. `None` without obstacles.
pub(super) fn loop_pyramid(
    grid: &OccupancyGrid,
    depth: u32,
) -> Result<Option<MaxPyramid>, GraphError> {
    let Some((min, max)) = grid.obstacle_bounds() else {
        return Ok(None);
    };
    let reach = (grid.likelihood_params().max_distance / grid.resolution()).ceil() as i32 + 2;
    let min = slam_grid::CellIndex::new(min.x - reach, min.y - reach);
    let max = slam_grid::CellIndex::new(max.x + reach, max.y + reach);
    // Compact: the cache holds several, and the search scores its poses on the exact
    // level 0 anyway.
    Ok(Some(MaxPyramid::new_compact(grid, min, max, depth)?))
}
