//! Likelihood fields: Thrun's endpoint model (PR §6.4) from exact distance transforms.
//!
//! Two ways to get one:
//! * implicitly, per tile, inside every [`crate::OccupancyGrid`]: computed lazily the first
//!   time a matcher looks at a tile, cached, shared between grid clones like the tiles
//!   themselves, and invalidated only when a write changes which cells are obstacles in the
//!   tile or its neighbours; matchers use this one;
//! * explicitly, over a rectangle of cells, as a dense [`LikelihoodField`] (for pictures,
//!   analysis, and tests).

pub(crate) mod edt;
mod field;
mod lazy;
mod params;

pub use field::LikelihoodField;
pub use params::LikelihoodParams;
