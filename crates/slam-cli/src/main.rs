//! The `slam` program: a thin wrapper around [`slam_cli::main_with_args`] that turns an error
//! into one line on stderr and a non-zero exit code.

use std::process::ExitCode;

fn main() -> ExitCode {
    // A panic is a bug, never a user mistake; report it on one line instead of a backtrace.
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!(
            "slam: internal error (a bug, please report it): {}{at}",
            msg.replace('\n', " ")
        );
    }));
    // Ctrl-C (and SIGTERM) asks `slam run` to stop at its next step, so it can leave no
    // half-written output; a second one ends the program at once (the outputs are staged
    // in `.slam-partial`, so even then nothing complete-looking is left).
    let _ = ctrlc::set_handler(|| {
        if slam_cli::request_stop() {
            eprintln!("slam: stopped");
            std::process::exit(130);
        }
        eprintln!("slam: stopping at the next step (Ctrl-C again to stop at once)");
    });
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    match slam_cli::main_with_args(std::env::args_os(), &mut out) {
        Ok(outcome) => ExitCode::from(outcome.exit_code()),
        Err(e) => {
            eprintln!("slam: error: {e}");
            ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(1))
        }
    }
}
