//! Data association for id-less observations.
//!
//! * [`compatibility`]: individual compatibility of an observation with a landmark (the
//!   Mahalanobis gate) and the cross-covariance of two predicted measurements.
//! * [`nearest`]: maximum-likelihood nearest neighbour with greedy conflict resolution.
//! * [`jcbb`]: joint compatibility branch and bound (Neira & Tardós 2001).

pub(crate) mod compatibility;
pub(crate) mod jcbb;
pub(crate) mod nearest;

pub(crate) use compatibility::{candidates, Candidate};
