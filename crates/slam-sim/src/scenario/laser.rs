//! The laser scenarios: `office` and `replay`.

use super::ScenarioOptions;
use crate::error::SimError;
use crate::LaserSimRun;

/// `office` (not yet implemented).
pub fn office(_opts: &ScenarioOptions) -> Result<LaserSimRun, SimError> {
    Err(SimError::InvalidWorld("office: not implemented yet".into()))
}

/// `replay` (not yet implemented).
pub fn replay(_opts: &ScenarioOptions) -> Result<LaserSimRun, SimError> {
    Err(SimError::InvalidWorld("replay: not implemented yet".into()))
}
