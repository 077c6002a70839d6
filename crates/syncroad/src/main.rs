//! The `syncroad` binary: the whole CLI is [`syncroad::host::main`]; each SUMO run
//! re-executes this binary as its worker process.

use std::process::ExitCode;

fn main() -> ExitCode {
    // A file-size limit fails the write that passes it (EFBIG, handled as a full disk) instead
    // of killing the CLI or its worker with nothing written.
    if let Err(e) = syncroad_sumo::survive_file_size_limit() {
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), "warning: {e}");
    }
    if syncroad_sumo::is_worker_invocation() {
        return syncroad_sumo::worker_main();
    }
    ExitCode::from(syncroad::host::main(std::env::args_os()))
}
