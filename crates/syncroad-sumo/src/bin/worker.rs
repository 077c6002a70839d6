//! `syncroad-sumo-worker`: runs one SUMO co-simulation request (see
//! `syncroad_sumo::worker_main`). Started by the supervisor, never by hand.

fn main() -> std::process::ExitCode {
    syncroad_sumo::worker_main()
}
