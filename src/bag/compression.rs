//! rosbag2's zstd compression, undone within limits: `compression_mode: message` (each message's
//! bytes one zstd frame) and `compression_mode: file` (each storage file one zstd stream,
//! `name.mcap.zstd` / `name.db3.zstd`), plus the zstd and lz4 chunks of MCAP files.
//!
//! Nothing is allocated from a size the input declares without checking it against a limit
//! first, and decompressed output is checked against the size declared for it.

use std::io::{BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// The most bytes one record, chunk or message may take once decompressed (1 GiB).
pub const MAX_RECORD: u64 = 1 << 30;

/// The first bytes of a zstd frame. A CDR message starts with `0x00` (its encapsulation), so a
/// message starting with these is a `message`-mode compressed one.
pub const ZSTD_MAGIC: [u8; 4] = [0x28, 0xb5, 0x2f, 0xfd];

/// Whether `data` starts like a zstd frame.
pub fn is_zstd(data: &[u8]) -> bool {
    data.starts_with(&ZSTD_MAGIC)
}

/// Decompresses one zstd frame (a `message`-mode message, an MCAP chunk) into `out` (cleared
/// first). `expected` is the size the container declares, if any: the frame must decompress to
/// exactly that many bytes. At most [`MAX_RECORD`] bytes.
pub fn zstd_into(
    zstd: &mut Option<zstd::bulk::Decompressor<'static>>,
    src: &[u8],
    expected: Option<u64>,
    out: &mut Vec<u8>,
) -> Result<(), String> {
    out.clear();
    let declared = match zstd::zstd_safe::get_frame_content_size(src) {
        Ok(size) => size,
        Err(_) => return Err("not a zstd frame".into()),
    };
    if let (Some(d), Some(e)) = (declared, expected) {
        if d != e {
            return Err(format!(
                "zstd frame says {d} bytes, its container {e} bytes"
            ));
        }
    }
    match declared.or(expected) {
        Some(size) => {
            if size > MAX_RECORD {
                return Err(format!(
                    "zstd frame of {size} bytes: more than the limit of {MAX_RECORD} bytes"
                ));
            }
            if zstd.is_none() {
                *zstd = Some(zstd::bulk::Decompressor::new().map_err(|e| format!("zstd: {e}"))?);
            }
            // The capacity is kept from one frame to the next: no allocation once it suffices.
            out.reserve(size as usize);
            let n = zstd
                .as_mut()
                .expect("made above")
                .decompress_to_buffer(src, out)
                .map_err(|e| format!("zstd: {e}"))?;
            if n as u64 != size {
                return Err(format!(
                    "zstd frame decompressed to {n} bytes, declared {size}"
                ));
            }
        }
        None => {
            // No size anywhere: streamed, growing with what actually comes out.
            let decoder =
                zstd::stream::read::Decoder::with_buffer(src).map_err(|e| format!("zstd: {e}"))?;
            bounded_read(decoder, MAX_RECORD, out, "zstd frame")?;
        }
    }
    Ok(())
}

/// Decompresses an LZ4 frame (an MCAP chunk) of `expected` bytes into `out` (cleared first).
pub fn lz4_into(src: &[u8], expected: u64, out: &mut Vec<u8>) -> Result<(), String> {
    out.clear();
    if expected > MAX_RECORD {
        return Err(format!(
            "lz4 data of {expected} bytes: more than the limit of {MAX_RECORD} bytes"
        ));
    }
    let decoder = lz4::Decoder::new(src).map_err(|e| format!("lz4: {e}"))?;
    bounded_read(decoder, expected, out, "lz4 frame")?;
    if out.len() as u64 != expected {
        return Err(format!(
            "lz4 frame decompressed to {} bytes, declared {expected}",
            out.len()
        ));
    }
    Ok(())
}

/// The start of a chunk whose compressed bytes were cut short (a file cut inside it): a streaming
/// decoder fed the bytes that exist, into `out` (cleared first), keeping everything it produced
/// before its input ran out (or turned out damaged), at most `limit` bytes (the size the chunk
/// declares, itself at most [`MAX_RECORD`]). Both decoders emit a compressed block once it is
/// whole (zstd blocks hold at most 128 KiB, lz4 frame blocks 64 KiB by default), so what comes
/// out is every block complete in `src`, and part of the next only when that one is stored
/// uncompressed.
pub fn prefix_into(
    compression: &str,
    src: &[u8],
    limit: u64,
    out: &mut Vec<u8>,
) -> Result<(), String> {
    out.clear();
    if limit > MAX_RECORD {
        return Err(format!(
            "{compression} data of {limit} bytes: more than the limit of {MAX_RECORD} bytes"
        ));
    }
    // The error that ends the stream is the cut itself: what was produced before it is kept
    // (`read_to_end` appends every byte read before an error).
    match compression {
        "zstd" => {
            if let Ok(decoder) = zstd::stream::read::Decoder::with_buffer(src) {
                let _ = decoder.take(limit).read_to_end(out);
            }
        }
        "lz4" => {
            if let Ok(decoder) = lz4::Decoder::new(src) {
                let _ = decoder.take(limit).read_to_end(out);
            }
        }
        other => {
            return Err(format!(
                "chunk compression '{other}' is not supported (zstd, lz4 or none)"
            ))
        }
    }
    Ok(())
}

/// Reads `from` to its end into `out`, failing past `limit` bytes (the size declared for it,
/// else [`MAX_RECORD`]): decompression stops one byte past the limit, so a frame that lies about
/// its size takes no more memory than the size it declared.
fn bounded_read(from: impl Read, limit: u64, out: &mut Vec<u8>, what: &str) -> Result<(), String> {
    let n = from
        .take(limit + 1)
        .read_to_end(out)
        .map_err(|e| format!("{what}: {e}"))?;
    if n as u64 > limit {
        return Err(if limit == MAX_RECORD {
            format!("{what} decompresses to more than the limit of {MAX_RECORD} bytes")
        } else {
            format!("{what} decompresses to more than the {limit} bytes declared for it")
        });
    }
    Ok(())
}

/// Whether a storage file is `file`-mode compressed (its name ends in `.zstd`).
pub fn is_zstd_file(path: &Path) -> bool {
    path.extension().is_some_and(|e| e == "zstd")
}

/// A `file`-mode compressed storage file, decompressed as it is read.
pub fn zstd_file_reader(path: &Path) -> Result<impl Read, String> {
    let file =
        std::fs::File::open(path).map_err(|e| format!("cannot open {}: {e}", path.display()))?;
    zstd::stream::read::Decoder::with_buffer(BufReader::with_capacity(1 << 20, file))
        .map_err(|e| format!("{}: zstd: {e}", path.display()))
}

/// A copy of a storage file in the temporary directory (never beside the bag), removed with
/// whatever SQLite made beside it (`-wal`, `-shm`, `-journal`) when dropped: the decompressed
/// copy of a `file`-mode compressed file, or an sqlite3 database with its write-ahead log.
#[derive(Debug)]
pub struct TempCopy {
    pub path: PathBuf,
}

impl TempCopy {
    /// A new name in the temporary directory for a copy of `path`.
    fn for_file(path: &Path) -> TempCopy {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let stem = path
            .file_stem()
            .map_or("bag".into(), |s| s.to_string_lossy().into_owned());
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        TempCopy {
            path: std::env::temp_dir().join(format!(
                "spatial_dynamics_{}_{n}_{stem}",
                std::process::id()
            )),
        }
    }

    /// `path` with `suffix` appended to its name (`x.db3` → `x.db3-wal`).
    fn sibling(path: &Path, suffix: &str) -> PathBuf {
        let mut name = path.as_os_str().to_owned();
        name.push(suffix);
        PathBuf::from(name)
    }
}

impl Drop for TempCopy {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
        for suffix in ["-wal", "-shm", "-journal"] {
            let _ = std::fs::remove_file(TempCopy::sibling(&self.path, suffix));
        }
    }
}

/// The write-ahead log beside sqlite3 database `path`, if it holds anything: a recorder killed
/// in WAL mode leaves its latest messages there, not yet in the database file.
pub fn write_ahead_log(path: &Path) -> Option<PathBuf> {
    let wal = TempCopy::sibling(path, "-wal");
    let len = std::fs::metadata(&wal).ok()?.len();
    (len > 0).then_some(wal)
}

/// A copy of sqlite3 database `path` and its write-ahead log `wal` in the temporary directory,
/// for SQLite to apply the log to (it would otherwise write beside the bag to do so). Stops
/// with an error, the copy removed, once `stop` is set.
pub fn copy_with_log(path: &Path, wal: &Path, stop: &AtomicBool) -> Result<TempCopy, String> {
    let copy = TempCopy::for_file(path);
    for (from, to) in [
        (path.to_path_buf(), copy.path.clone()),
        (wal.to_path_buf(), TempCopy::sibling(&copy.path, "-wal")),
    ] {
        let reader = std::fs::File::open(&from)
            .map_err(|e| format!("cannot open {}: {e}", from.display()))?;
        pump(reader, &from, &to, u64::MAX, stop)?;
    }
    Ok(copy)
}

/// Copies `reader` (the contents of `from`, decompressed if it is compressed) into the new file
/// `to` a MiB at a time, checking `stop` before each MiB (a signal: an error) and refusing more
/// than `limit` bytes.
fn pump(
    mut reader: impl Read,
    from: &Path,
    to: &Path,
    limit: u64,
    stop: &AtomicBool,
) -> Result<(), String> {
    let mut out = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(to)
        .map_err(|e| format!("cannot create {}: {e}", to.display()))?;
    let mut buf = vec![0u8; 1 << 20];
    let mut total = 0u64;
    loop {
        if stop.load(Ordering::Relaxed) {
            return Err(format!(
                "interrupted by a signal while reading {} into {}: nothing written",
                from.display(),
                to.display()
            ));
        }
        let n = match reader.read(&mut buf) {
            Ok(0) => return Ok(()),
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(format!("{}: after {total} bytes read: {e}", from.display())),
        };
        total += n as u64;
        if total > limit {
            return Err(format!(
                "{}: decompresses to more than {limit} bytes (100 times its size): refused",
                from.display()
            ));
        }
        out.write_all(&buf[..n])
            .map_err(|e| format!("cannot write {}: {e}", to.display()))?;
    }
}

/// The most a `file`-mode compressed file may grow to: 100 times its compressed size, and at
/// least 1 GiB (sqlite3 databases compress 3-10 times; a larger ratio is a zstd bomb).
fn file_limit(compressed: u64) -> u64 {
    compressed.saturating_mul(100).max(1 << 30)
}

/// Decompresses a `file`-mode compressed storage file into a [`TempCopy`], streaming; stops
/// with an error, the copy removed, once `stop` is set.
pub fn decompress_to_temp(path: &Path, stop: &AtomicBool) -> Result<TempCopy, String> {
    let compressed = std::fs::metadata(path)
        .map_err(|e| format!("cannot open {}: {e}", path.display()))?
        .len();
    let limit = file_limit(compressed);
    let copy = TempCopy::for_file(path);
    pump(
        zstd_file_reader(path)?.take(limit + 1),
        path,
        &copy.path,
        limit,
        stop,
    )?;
    Ok(copy)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A signal (`stop` set) ends the copies a bag's sqlite3 files need with an error and leaves
    /// no copy behind; unset, they are whole.
    #[test]
    fn copies_stop_at_a_signal_and_leave_nothing() {
        let dir = std::env::temp_dir().join(format!("sd_stop_test_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let data: Vec<u8> = (0..3_000_000u32).map(|i| (i % 251) as u8).collect();
        let (db, wal, packed) = (
            dir.join("b.db3"),
            dir.join("b.db3-wal"),
            dir.join("b.db3.zstd"),
        );
        std::fs::write(&db, &data).unwrap();
        std::fs::write(&wal, &data[..1000]).unwrap();
        std::fs::write(&packed, zstd::encode_all(&data[..], 3).unwrap()).unwrap();
        let running = AtomicBool::new(false);
        let copy = decompress_to_temp(&packed, &running).unwrap();
        assert_eq!(std::fs::read(&copy.path).unwrap(), data);
        let copy = copy_with_log(&db, &wal, &running).unwrap();
        assert_eq!(std::fs::read(&copy.path).unwrap(), data);
        drop(copy);

        let stopped = AtomicBool::new(true);
        let temp_entries = || {
            let prefix = format!("spatial_dynamics_{}_", std::process::id());
            let entries = std::fs::read_dir(std::env::temp_dir()).unwrap();
            let names = entries.map(|e| e.unwrap().file_name().to_string_lossy().into_owned());
            // Only this test's copies: other tests may make copies meanwhile.
            names
                .filter(|n| n.starts_with(&prefix) && n.contains("_stop_test"))
                .count()
        };
        let before = temp_entries();
        let err = decompress_to_temp(&packed, &stopped).unwrap_err();
        assert!(err.contains("interrupted by a signal"), "{err}");
        let err = copy_with_log(&db, &wal, &stopped).unwrap_err();
        assert!(err.contains("interrupted by a signal"), "{err}");
        assert_eq!(temp_entries(), before);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn frames_decompress_to_their_declared_size_only() {
        let data: Vec<u8> = (0..100_000u32)
            .flat_map(|i| (i % 251).to_le_bytes())
            .collect();
        let frame = zstd::bulk::compress(&data, 3).unwrap();
        let mut ctx = None;
        let mut out = Vec::new();
        zstd_into(&mut ctx, &frame, None, &mut out).unwrap();
        assert_eq!(out, data);
        zstd_into(&mut ctx, &frame, Some(data.len() as u64), &mut out).unwrap();
        assert_eq!(out, data);
        let err = zstd_into(&mut ctx, &frame, Some(10), &mut out).unwrap_err();
        assert!(err.contains("container 10 bytes"), "{err}");
        // A frame whose header declares 2^40 bytes is refused before anything is allocated.
        // (Frame header: magic, descriptor 0xe0 = single segment with an 8-byte content size.)
        let mut huge = ZSTD_MAGIC.to_vec();
        huge.push(0xe0);
        huge.extend_from_slice(&(1u64 << 40).to_le_bytes());
        huge.extend_from_slice(&frame[6..]);
        let err = zstd_into(&mut ctx, &huge, None, &mut out).unwrap_err();
        assert!(err.contains("limit"), "{err}");
        // Not zstd at all; truncated.
        assert!(zstd_into(&mut ctx, b"\0\x01\0\0abc", None, &mut out).is_err());
        assert!(zstd_into(&mut ctx, &frame[..frame.len() / 2], None, &mut out).is_err());
        // lz4: its declared size is checked.
        let mut enc = lz4::EncoderBuilder::new().build(Vec::new()).unwrap();
        enc.write_all(&data).unwrap();
        let (lz, r) = enc.finish();
        r.unwrap();
        lz4_into(&lz, data.len() as u64, &mut out).unwrap();
        assert_eq!(out, data);
        let err = lz4_into(&lz, 5, &mut out).unwrap_err();
        assert!(err.contains("more than the 5 bytes declared"), "{err}");
        // Stopped one byte past the declared size: no more memory than declared.
        assert_eq!(out.len(), 6);
        assert!(lz4_into(&lz, 1 << 41, &mut out)
            .unwrap_err()
            .contains("limit"));
    }
}
