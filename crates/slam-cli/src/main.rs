//! The `slam` command-line program.

fn main() {
    eprintln!("slam: not yet available");
    std::process::exit(2);
}
