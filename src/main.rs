//! The `spatial_dynamics` command: `model`, `eval`, `bench`, `chart`, `simulate`, `replay`, `node`.

fn main() -> std::process::ExitCode {
    spatial_dynamics::cli_main()
}
