//! `spatial_dynamics eval`: one JSON request per line on stdin, one JSON answer per line on
//! stdout, in order (see [`spatial_dynamics_core::requests`] for the requests). A bad request answers
//! `{"error": "..."}` and the loop goes on. Numbers are printed in the shortest form that parses
//! back to the same f64.

use super::ModelArgs;
use spatial_dynamics_core::requests::answer_line;
use spatial_dynamics_core::Workspace;
use std::io::{BufRead, Write};

/// Runs the request loop until stdin closes.
pub fn run(args: &ModelArgs) -> Result<(), String> {
    let model = args.load()?;
    let mut ws = Workspace::new(&model);
    let stdin = std::io::stdin();
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    let mut input = stdin.lock();
    let mut line = Vec::new();
    loop {
        line.clear();
        // Bytes, not a String: a line that is not UTF-8 is answered like any bad request.
        if input
            .read_until(b'\n', &mut line)
            .map_err(|e| format!("reading stdin: {e}"))?
            == 0
        {
            break;
        }
        if line.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        let answer = answer_line(&model, &mut ws, &line);
        writeln!(out, "{answer}")
            .and_then(|_| out.flush())
            .map_err(|e| format!("writing stdout: {e}"))?;
    }
    Ok(())
}
