//! # slam-grid: occupancy grids and scan matching
//!
//! Will hold log-odds occupancy grids on copy-on-write tiles, beam tracing, likelihood
//! fields from exact distance transforms, and scan matchers (hill climbing, correlative,
//! Gauss-Newton), plus map export.
