//! `spatial_dynamics eval`: one JSON request per line on stdin, one JSON answer per line on
//! stdout, in order (see [`spatial_dynamics_core::requests`] for the requests). A bad request answers
//! `{"error": "..."}` and the loop goes on. Numbers are printed in the shortest form that parses
//! back to the same f64.

use super::ModelArgs;
use spatial_dynamics_core::requests::answer_line;
use spatial_dynamics_core::Workspace;
use std::io::{BufRead, Read, Write};

/// The longest request line: 16 MiB, far above what any model within the workspace budget
/// needs (four vectors of 5,000 coordinates in full precision take about 0.5 MiB). A longer
/// line is answered with an error and skipped, never held whole.
const MAX_LINE: usize = 16 << 20;

/// Runs the request loop until stdin closes. Blank lines are skipped, unanswered.
pub fn run(args: &ModelArgs) -> Result<(), String> {
    let model = args.load()?;
    let mut ws = Workspace::new(&model);
    let stdin = std::io::stdin();
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    let mut input = stdin.lock();
    let mut line = Vec::new();
    for number in 1u64.. {
        line.clear();
        // Bytes, not a String: a line that is not UTF-8 is answered like any bad request.
        let read = (&mut input)
            .take(MAX_LINE as u64 + 1)
            .read_until(b'\n', &mut line)
            .map_err(|e| format!("reading stdin: {e}"))?;
        if read == 0 {
            break;
        }
        let answer = if line.len() > MAX_LINE && line.last() != Some(&b'\n') {
            skip_line(&mut input).map_err(|e| format!("reading stdin: {e}"))?;
            serde_json::json!({
                "error": format!("bad request: line {number} is longer than {MAX_LINE} bytes")
            })
        } else if line.iter().all(u8::is_ascii_whitespace) {
            continue;
        } else {
            answer_line(&model, &mut ws, &line)
        };
        writeln!(out, "{answer}")
            .and_then(|_| out.flush())
            .map_err(|e| format!("writing stdout: {e}"))?;
    }
    Ok(())
}

/// Reads and drops the rest of the current line (through its newline, or to the end).
fn skip_line(input: &mut impl BufRead) -> std::io::Result<()> {
    loop {
        let buf = input.fill_buf()?;
        if buf.is_empty() {
            return Ok(());
        }
        match buf.iter().position(|&b| b == b'\n') {
            Some(i) => {
                input.consume(i + 1);
                return Ok(());
            }
            None => {
                let n = buf.len();
                input.consume(n);
            }
        }
    }
}
