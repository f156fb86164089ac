//! The `splattrack` command line (docs/formats.md).

mod cli;

use clap::Parser;
use clap::error::ErrorKind;

fn main() -> std::process::ExitCode {
    // Mesa's Vulkan drivers probe for a Wayland display and print an error
    // line when XDG_RUNTIME_DIR is unset, as on headless machines; give them
    // a directory so that stderr carries only our own messages. Safe: no
    // other thread exists yet.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir()) };
    }
    let args = match cli::Cli::try_parse() {
        Ok(a) => a,
        Err(e) => return usage_error(e),
    };
    cli::init_logging(args.verbose);
    match cli::run(args) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // One line naming the file and the problem: the whole chain, joined.
            let msg: Vec<String> = e.chain().map(|c| c.to_string()).collect();
            let mut line = String::new();
            for m in msg {
                if !line.contains(&m) {
                    if !line.is_empty() {
                        line.push_str(": ");
                    }
                    line.push_str(&m);
                }
            }
            eprintln!("error: {}", line.replace('\n', " "));
            std::process::ExitCode::FAILURE
        }
    }
}

/// A command-line error in one line (docs/formats.md: "non-zero with a one-line
/// reason on stderr"): clap's message up to its usage text, its lines
/// joined. Help and version requests print as clap prints them.
fn usage_error(e: clap::Error) -> std::process::ExitCode {
    if matches!(
        e.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        e.exit();
    }
    let text = e.to_string();
    let line: Vec<&str> = text
        .lines()
        .map(str::trim)
        .take_while(|l| !l.starts_with("Usage:") && !l.starts_with("For more information"))
        .filter(|l| !l.is_empty())
        .collect();
    eprintln!("{}", line.join(" "));
    std::process::ExitCode::from(2)
}
