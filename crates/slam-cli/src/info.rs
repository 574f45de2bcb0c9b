//! `slam info`: what a dataset holds, without running anything.

use crate::cli::InfoArgs;
use crate::error::CliError;
use std::io::Write;

/// Writes slam-io's description of the dataset at `args.path` ([`slam_io::dataset_info`]):
/// for a ROS bag its topics, types, counts, rates, span, laser geometry and odometry
/// sources; for the other formats their record counts and laser geometry.
pub fn info(args: &InfoArgs, out: &mut dyn Write) -> Result<(), CliError> {
    let text = crate::error::with_flags(&slam_io::dataset_info(&args.path)?);
    let _ = writeln!(out, "{text}");
    Ok(())
}
