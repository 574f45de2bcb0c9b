//! `slam list`: the filters and the scenarios.

use crate::filters::filters;
use slam_sim::scenario;
use std::io::Write;

/// Prints the filters and scenarios to `out`.
pub(crate) fn list(out: &mut dyn Write) {
    let _ = writeln!(out, "Filters (slam run --filter NAME):");
    for f in filters() {
        let _ = writeln!(
            out,
            "  {:<10} {:<8} {}",
            f.name,
            f.kind.as_str(),
            f.description
        );
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "Scenarios (slam run --sim NAME, slam sim NAME; all available):"
    );
    for s in scenario::list() {
        let kind = s.kind.as_str();
        let name = if s.name == "replay" {
            "replay:<map.yaml>".to_string()
        } else {
            s.name.to_string()
        };
        let _ = writeln!(out, "  {name:<18} {kind:<8} {}", s.description);
    }
}
