//! Output files written whole or not at all: a temporary file beside the final one, renamed
//! over it only when the run keeps it, removed otherwise (on an error, or when the process
//! unwinds), so a failed run leaves an earlier output as it was and nothing half-written.

use std::path::{Path, PathBuf};

/// An output being written: `DIR/.NAME.PID.partial` for output `DIR/NAME`, removed when dropped
/// unless kept.
pub struct PartialFile {
    pub path: PathBuf,
    kept: bool,
}

impl PartialFile {
    /// The temporary path for output `out` (nothing is created yet).
    pub fn beside(out: &Path) -> Result<PartialFile, String> {
        let name = out
            .file_name()
            .ok_or_else(|| format!("{}: not a file name", out.display()))?;
        let mut partial = std::ffi::OsString::from(".");
        partial.push(name);
        partial.push(format!(".{}.partial", std::process::id()));
        Ok(PartialFile {
            path: out.with_file_name(partial),
            kept: false,
        })
    }

    /// Renames the finished file to `out` (replacing it).
    pub fn keep_as(mut self, out: &Path) -> Result<(), String> {
        std::fs::rename(&self.path, out).map_err(|e| {
            format!(
                "cannot rename {} to {}: {e}",
                self.path.display(),
                out.display()
            )
        })?;
        self.kept = true;
        Ok(())
    }
}

impl Drop for PartialFile {
    fn drop(&mut self) {
        if !self.kept {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// Whether two paths name the same existing file or directory (the same device and inode on
/// Unix: hard links and different spellings included).
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        #[cfg(unix)]
        (Ok(x), Ok(y)) => {
            use std::os::unix::fs::MetadataExt;
            x.dev() == y.dev() && x.ino() == y.ino()
        }
        #[cfg(not(unix))]
        (Ok(_), Ok(_)) => std::fs::canonicalize(a).ok() == std::fs::canonicalize(b).ok(),
        _ => false,
    }
}
