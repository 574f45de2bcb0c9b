//! Measurement models.
//!
//! * [`range_bearing`]: point landmarks observed by range and bearing (PR eq. 6.40 and
//!   table 10.1 line 12–16), with the inverse model used to initialise new landmarks.

pub mod range_bearing;

pub use range_bearing::{InverseRangeBearing, PredictedRangeBearing, RangeBearingModel};
