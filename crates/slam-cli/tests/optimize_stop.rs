//! `slam optimize` honours Ctrl-C like `slam run` (issue 32): a stop asked for while it
//! runs leaves an earlier output in the folder as it was and ends with the interrupted
//! error (exit code 130). Alone in its test binary: the stop flag is process-wide.

use slam_cli::error::CliError;

#[test]
fn a_stopped_optimize_keeps_the_earlier_output() {
    let d = std::env::temp_dir().join(format!("slam-cli-optimize-stop-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    // A triangle of three poses with one loop closure (g2o SE2 format).
    let g = d.join("g.g2o");
    let info = "1 0 0 1 0 1";
    std::fs::write(
        &g,
        format!(
            "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1.1 0 0\nVERTEX_SE2 2 1 0.9 0\nFIX 0\n\
             EDGE_SE2 0 1 1 0 0 {info}\nEDGE_SE2 1 2 0 1 0 {info}\nEDGE_SE2 2 0 -1 -1 0 {info}\n"
        ),
    )
    .unwrap();
    let out = d.join("out");
    let run = || {
        let args = [
            "slam",
            "optimize",
            g.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        slam_cli::main_with_args(args, &mut Vec::new())
    };
    run().unwrap();
    let before = std::fs::read(out.join("optimized.g2o")).unwrap();
    let result = std::fs::read(out.join("result.json")).unwrap();
    // The earlier output made to differ: a stopped run must not put it back either.
    std::fs::write(out.join("optimized.g2o"), b"earlier\n").unwrap();
    assert!(!slam_cli::request_stop());
    let e = run().unwrap_err();
    assert!(matches!(e, CliError::Interrupted { .. }), "{e}");
    assert_eq!(e.exit_code(), 130);
    assert_eq!(
        std::fs::read(out.join("optimized.g2o")).unwrap(),
        b"earlier\n"
    );
    assert_eq!(std::fs::read(out.join("result.json")).unwrap(), result);
    assert!(!before.is_empty());
    let _ = std::fs::remove_dir_all(&d);
}
