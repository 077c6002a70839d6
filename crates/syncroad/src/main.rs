//! The `syncroad` binary: the whole CLI is [`syncroad::host::main`]; each SUMO run
//! re-executes this binary as its worker process.

use std::process::ExitCode;

fn main() -> ExitCode {
    if syncroad_sumo::is_worker_invocation() {
        return syncroad_sumo::worker_main();
    }
    ExitCode::from(syncroad::host::main(std::env::args_os()))
}
