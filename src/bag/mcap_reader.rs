//! MCAP files read record by record (the MCAP specification, version 0): every length and
//! count is checked against the bytes that remain (in the file, the record or the chunk) before
//! anything is sliced or allocated, so damaged bytes give an error naming the byte offset, never
//! a panic or a huge allocation.
//!
//! A record is `opcode: u8, length: u64, body`; fields are little-endian, strings and byte arrays
//! carry a `u32` length (a chunk's records a `u64` one), maps a `u32` byte length.
//!
//! Messages are read linearly from the data section (the summary is not needed), so a file cut
//! short by a killed recorder (no data end, summary, footer or closing magic) still gives every
//! complete record before the cut, including those of a chunk the cut falls in (decoded as far as
//! its bytes go): [`read`] then returns a note saying where it stopped. A file
//! that does end with the magic is complete, and a record running past its end is an error.
//! A `file`-mode compressed file (`.mcap.zstd`) is read the same way through a zstd stream.

use super::compression::{self, MAX_RECORD};
use super::{match_topic, Flow, RawMessage, TopicInfo, Visitor, Wanted};
use mcap::records::op;
use std::collections::HashMap;
use std::fmt;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";
/// A footer record: opcode, length 20, summary start, summary offset start, summary CRC.
const FOOTER_LEN: u64 = 1 + 8 + 20;

/// Where a record is: at a byte of the file, or at an offset in the records of a chunk.
#[derive(Clone, Copy, Debug)]
enum At {
    File(u64),
    Chunk { chunk: u64, offset: usize },
}

impl fmt::Display for At {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            At::File(at) => write!(f, "the record at byte {at}"),
            At::Chunk { chunk, offset } => write!(
                f,
                "the record at offset {offset} of the chunk at byte {chunk}"
            ),
        }
    }
}

/// The fields of one record body, read in order with bounds checks.
struct Fields<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Fields<'a> {
    fn take(&mut self, n: u64, field: &str) -> Result<&'a [u8], String> {
        let left = self.data.len() - self.pos;
        if n > left as u64 {
            return Err(format!(
                "{field} needs {n} bytes at offset {} of a {}-byte record",
                self.pos,
                self.data.len()
            ));
        }
        let bytes = &self.data[self.pos..self.pos + n as usize];
        self.pos += n as usize;
        Ok(bytes)
    }
    fn u16(&mut self, field: &str) -> Result<u16, String> {
        Ok(u16::from_le_bytes(
            self.take(2, field)?.try_into().expect("2"),
        ))
    }
    fn u32(&mut self, field: &str) -> Result<u32, String> {
        Ok(u32::from_le_bytes(
            self.take(4, field)?.try_into().expect("4"),
        ))
    }
    fn u64(&mut self, field: &str) -> Result<u64, String> {
        Ok(u64::from_le_bytes(
            self.take(8, field)?.try_into().expect("8"),
        ))
    }
    /// A `u32`-prefixed byte array (also a map, skipped whole).
    fn bytes32(&mut self, field: &str) -> Result<&'a [u8], String> {
        let n = self.u32(field)?;
        self.take(u64::from(n), field)
    }
    fn string(&mut self, field: &str) -> Result<&'a str, String> {
        std::str::from_utf8(self.bytes32(field)?).map_err(|_| format!("{field} is not UTF-8"))
    }
    fn rest(&mut self) -> &'a [u8] {
        let rest = &self.data[self.pos..];
        self.pos = self.data.len();
        rest
    }
}

/// Reads `buf` full from `src`; the number of bytes read (fewer only at the end of the input).
fn read_full(src: &mut impl Read, buf: &mut [u8], at: u64) -> Result<usize, String> {
    let mut n = 0;
    while n < buf.len() {
        match src.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(format!("read failed at byte {}: {e}", at + n as u64)),
        }
    }
    Ok(n)
}

/// The next top-level record, or how the input ended.
enum Next {
    Record {
        opcode: u8,
        len: u64,
        at: u64,
    },
    /// The input ends (or the section read ends) between records.
    End,
    /// The input ends inside a record: the note says where.
    Cut(String),
}

/// The records of a file (or of its summary section), one after the other.
struct Records<R> {
    src: R,
    pos: u64,
    /// Where the bytes read end, when known (not through a zstd stream).
    size: Option<u64>,
    /// Whether the file ends with the closing magic: then a record past its end is damage,
    /// not a cut.
    complete: bool,
    /// In a complete file, where its footer says the data section ends: the summary's start,
    /// else the summary offsets' start, else the footer's.
    data_section_end: Option<u64>,
}

impl<R: Read> Records<R> {
    fn next(&mut self) -> Result<Next, String> {
        let at = self.pos;
        if self.size == Some(at) {
            return Ok(Next::End);
        }
        let mut head = [0u8; 9];
        let n = read_full(&mut self.src, &mut head, at)?;
        self.pos += n as u64;
        if n == 0 {
            return Ok(Next::End);
        }
        if n < head.len() {
            return Ok(Next::Cut(format!(
                "the file ends at byte {} inside the header of a record at byte {at}",
                self.pos
            )));
        }
        let opcode = head[0];
        let len = u64::from_le_bytes(head[1..].try_into().expect("8"));
        if let Some(size) = self.size {
            let left = size - self.pos;
            // A cut chunk is still read, as far as it goes ([`Reader::partial_chunk`]).
            if len > left && (self.complete || opcode != op::CHUNK) {
                return if self.complete {
                    Err(format!(
                        "the record at byte {at} (opcode {opcode:#04x}) claims {len} bytes, {left} remain"
                    ))
                } else {
                    Ok(Next::Cut(format!(
                        "the file ends at byte {size}, inside the record at byte {at} \
                         (opcode {opcode:#04x}, {len} bytes)"
                    )))
                };
            }
        }
        Ok(Next::Record { opcode, len, at })
    }

    /// The body of the record just announced, into `buf` (its capacity reused); `false` when the
    /// input ends first. Memory grows with the bytes actually read, never with the length claimed.
    fn body(&mut self, len: u64, buf: &mut Vec<u8>) -> Result<bool, String> {
        buf.clear();
        let n = (&mut self.src)
            .take(len)
            .read_to_end(buf)
            .map_err(|e| format!("read failed at byte {}: {e}", self.pos))?;
        self.pos += n as u64;
        Ok(n as u64 == len)
    }

    /// A data end (or, without one, the footer) ends the data section: it must have its
    /// record's length and, in a complete file, stand where the footer says the data section
    /// ends. A damaged opcode that reads as either would otherwise end the reading early and
    /// drop every message after it without a word.
    fn check_data_section_end(&self, opcode: u8, len: u64, at: u64) -> Result<(), String> {
        let (name, body) = if opcode == op::DATA_END {
            ("data end", 4)
        } else {
            ("footer", 20)
        };
        if len != body {
            return Err(format!(
                "the record at byte {at} has the opcode of a {name} ({opcode:#04x}) but claims \
                 {len} bytes, not {body}: the data section is damaged there"
            ));
        }
        let end = if opcode == op::DATA_END {
            at + 9 + body
        } else {
            at
        };
        match self.data_section_end {
            Some(expected) if expected != end => Err(format!(
                "a {name} record at byte {at} ends the data section at byte {end}, but the \
                 footer says it ends at byte {expected}: the data section is damaged there"
            )),
            _ => Ok(()),
        }
    }

    /// Skips the body of the record just announced; `false` when the input ends first.
    fn skip(&mut self, len: u64) -> Result<bool, String> {
        let n = std::io::copy(&mut (&mut self.src).take(len), &mut std::io::sink())
            .map_err(|e| format!("read failed at byte {}: {e}", self.pos))?;
        self.pos += n;
        Ok(n == len)
    }
}

/// How reading one file ended.
#[derive(Debug)]
pub struct Ended {
    pub flow: Flow,
    /// A warning about the file: it was cut short (where, and the last log time reached), or
    /// (sqlite3) messages were skipped (how many, and the first).
    pub note: Option<String>,
}

/// The message-reading state of one file.
struct Reader<'a, 'v> {
    wanted: &'a [Wanted<'a>],
    visit: &'a mut Visitor<'v>,
    schemas: HashMap<u16, String>,
    /// Channel id → index in `wanted` (None: not wanted).
    channels: HashMap<u16, Option<usize>>,
    last: (u16, Option<usize>),
    /// Log time of the last message read (any topic).
    last_log_time: Option<u64>,
    messages: u64,
    zstd: Option<zstd::bulk::Decompressor<'static>>,
    chunk: Vec<u8>,
    message: Vec<u8>,
}

impl Reader<'_, '_> {
    fn record(&mut self, opcode: u8, body: &[u8], at: At) -> Result<Flow, String> {
        let mut f = Fields { data: body, pos: 0 };
        let context = |e: String| format!("{at}: {e}");
        match opcode {
            op::MESSAGE => {
                let channel = f.u16("message channel id").map_err(context)?;
                f.u32("message sequence").map_err(context)?;
                let log_time = f.u64("message log time").map_err(context)?;
                f.u64("message publish time").map_err(context)?;
                if channel != self.last.0 {
                    let Some(&index) = self.channels.get(&channel) else {
                        return Err(context(format!("a message on unknown channel {channel}")));
                    };
                    self.last = (channel, index);
                }
                self.last_log_time = Some(log_time);
                self.messages += 1;
                let Some(topic) = self.last.1 else {
                    return Ok(Flow::Continue);
                };
                let mut data = f.rest();
                if compression::is_zstd(data) {
                    // rosbag2's `message` compression mode: each message one zstd frame.
                    compression::zstd_into(&mut self.zstd, data, None, &mut self.message)
                        .map_err(|e| context(format!("message data: {e}")))?;
                    data = &self.message;
                }
                (self.visit)(RawMessage {
                    topic,
                    log_time,
                    data,
                })
            }
            op::SCHEMA => {
                let id = f.u16("schema id").map_err(context)?;
                let name = f.string("schema name").map_err(context)?;
                self.schemas.insert(id, name.to_string());
                Ok(Flow::Continue)
            }
            op::CHANNEL => {
                let id = f.u16("channel id").map_err(context)?;
                let schema = f.u16("channel schema id").map_err(context)?;
                let topic = f.string("channel topic").map_err(context)?;
                let encoding = f.string("channel message encoding").map_err(context)?;
                let type_name = self.schemas.get(&schema).map_or("", String::as_str);
                let index = match_topic(self.wanted, topic, type_name, encoding)?;
                self.channels.insert(id, index);
                if self.last.0 == id {
                    self.last = (id, index);
                }
                Ok(Flow::Continue)
            }
            op::CHUNK => {
                let At::File(chunk_at) = at else {
                    return Err(context("a chunk inside a chunk".into()));
                };
                self.chunk_records(&mut f, chunk_at).map_err(context)
            }
            _ => Ok(Flow::Continue),
        }
    }

    /// A chunk: its records decompressed (bounded by [`MAX_RECORD`]), CRC-checked when it has
    /// one, and read in order.
    fn chunk_records(&mut self, f: &mut Fields<'_>, chunk_at: u64) -> Result<Flow, String> {
        f.u64("chunk start time")?;
        f.u64("chunk end time")?;
        let size = f.u64("chunk uncompressed size")?;
        let crc = f.u32("chunk uncompressed crc")?;
        let compression = f.string("chunk compression")?;
        let len = f.u64("chunk records length")?;
        let records = f.take(len, "chunk records")?;
        let mut buf = std::mem::take(&mut self.chunk);
        let plain: &[u8] = match compression {
            "" => {
                if size != len {
                    return Err(format!(
                        "an uncompressed chunk of {len} bytes says {size} bytes"
                    ));
                }
                records
            }
            "zstd" => {
                compression::zstd_into(&mut self.zstd, records, Some(size), &mut buf)?;
                &buf
            }
            "lz4" => {
                compression::lz4_into(records, size, &mut buf)?;
                &buf
            }
            other => {
                return Err(format!(
                    "chunk compression '{other}' is not supported (zstd, lz4 or none)"
                ))
            }
        };
        if crc != 0 && crc32fast::hash(plain) != crc {
            return Err("the chunk's CRC does not match its records".into());
        }
        let result = self.chunk_body(plain, chunk_at, false);
        self.chunk = buf;
        result
    }

    /// A chunk the file ends inside (`body`: its bytes before the cut at byte `end`), read as
    /// `mcap recover` does: its records decoded as far as the bytes present go (for zstd and
    /// lz4, the blocks complete before the cut, see [`compression::prefix_into`]), then every
    /// record whose header and body are complete. Its CRC covers the whole chunk, so it cannot
    /// be checked. The flow, and the note saying what was recovered.
    fn partial_chunk(
        &mut self,
        body: &[u8],
        chunk_at: u64,
        len: u64,
        end: u64,
    ) -> Result<(Flow, String), String> {
        let cut = format!(
            "the file ends at byte {end} inside the chunk at byte {chunk_at} ({len} bytes)"
        );
        let mut f = Fields { data: body, pos: 0 };
        let header = (|| -> Result<_, String> {
            f.take(8 + 8, "chunk times")?;
            let size = f.u64("chunk uncompressed size")?;
            f.u32("chunk uncompressed crc")?;
            let compression = f.string("chunk compression")?;
            f.u64("chunk records length")?;
            Ok((size, compression))
        })();
        let Ok((size, compression)) = header else {
            return Ok((Flow::Continue, format!("{cut}, before its first record")));
        };
        let records = f.rest();
        let context = |e: String| format!("{}: {e}", At::File(chunk_at));
        if size > MAX_RECORD {
            return Err(context(format!(
                "the chunk says {size} bytes uncompressed: more than the limit of {MAX_RECORD}"
            )));
        }
        let mut buf = std::mem::take(&mut self.chunk);
        let plain: &[u8] = if compression.is_empty() {
            records
        } else {
            compression::prefix_into(compression, records, size, &mut buf).map_err(context)?;
            &buf
        };
        let before = self.messages;
        let flow = self.chunk_body(plain, chunk_at, true);
        let decoded = if compression.is_empty() {
            String::new()
        } else {
            format!(
                " ({compression}, {} of its {size} bytes decoded)",
                plain.len()
            )
        };
        self.chunk = buf;
        let note = format!(
            "{cut}: recovered {} messages from its records before the cut{decoded}, \
             its CRC unchecked (it covers the whole chunk)",
            self.messages - before
        );
        Ok((flow.map_err(context)?, note))
    }

    /// The records of a chunk, in order. `partial`: the chunk was cut, and its records end at
    /// the first incomplete one instead of that being an error.
    fn chunk_body(&mut self, plain: &[u8], chunk: u64, partial: bool) -> Result<Flow, String> {
        let mut offset = 0usize;
        while offset < plain.len() {
            let at = At::Chunk { chunk, offset };
            let left = plain.len() - offset;
            let incomplete = left < 9
                || u64::from_le_bytes(plain[offset + 1..offset + 9].try_into().expect("8"))
                    > (left - 9) as u64;
            if partial && incomplete {
                break;
            }
            if left < 9 {
                return Err(format!("{at}: {left} bytes, less than a record header"));
            }
            let opcode = plain[offset];
            let len = u64::from_le_bytes(plain[offset + 1..offset + 9].try_into().expect("8"));
            if len > (left - 9) as u64 {
                return Err(format!(
                    "{at} (opcode {opcode:#04x}) claims {len} bytes, {} remain in the chunk",
                    left - 9
                ));
            }
            let body = &plain[offset + 9..offset + 9 + len as usize];
            if opcode == op::CHUNK {
                return Err(format!("{at}: a chunk inside a chunk"));
            }
            if self.record(opcode, body, at)? == Flow::Stop {
                return Ok(Flow::Stop);
            }
            offset += 9 + len as usize;
        }
        Ok(Flow::Continue)
    }

    fn cut_note(&self, note: String) -> String {
        match self.last_log_time {
            Some(t) => format!(
                "{note}; replayed the {} complete messages before it, the last at log time {}.{:09} s",
                self.messages,
                t / 1_000_000_000,
                t % 1_000_000_000
            ),
            None => format!("{note}; no complete message before it"),
        }
    }
}

/// Opens an MCAP file for [`read`]: its records after the magic, with its size and whether it
/// ends with the closing magic (uncompressed files), or a zstd stream (`.mcap.zstd`).
fn open_records(path: &Path) -> Result<Records<Box<dyn Read>>, String> {
    if compression::is_zstd_file(path) {
        return Ok(Records {
            src: Box::new(compression::zstd_file_reader(path)?),
            pos: 0,
            size: None,
            complete: false,
            data_section_end: None,
        });
    }
    let mut file = File::open(path).map_err(|e| format!("cannot open: {e}"))?;
    let size = file.metadata().map_err(|e| e.to_string())?.len();
    let mut complete = false;
    let mut data_section_end = None;
    if size >= 16 {
        let mut tail = [0u8; 8];
        file.seek(SeekFrom::End(-8)).map_err(|e| e.to_string())?;
        complete = read_full(&mut file, &mut tail, size - 8)? == 8 && &tail == MAGIC;
        if complete && size >= 8 + FOOTER_LEN + 8 {
            let footer_at = size - 8 - FOOTER_LEN;
            let mut footer = [0u8; FOOTER_LEN as usize];
            file.seek(SeekFrom::Start(footer_at))
                .map_err(|e| e.to_string())?;
            if read_full(&mut file, &mut footer, footer_at)? == footer.len()
                && footer[0] == op::FOOTER
                && footer[1..9] == 20u64.to_le_bytes()
            {
                let field = |k: usize| u64::from_le_bytes(footer[k..k + 8].try_into().expect("8"));
                let (summary, offsets) = (field(9), field(17));
                data_section_end = [summary, offsets, footer_at]
                    .into_iter()
                    .find(|&at| at != 0);
            }
        }
        file.seek(SeekFrom::Start(0)).map_err(|e| e.to_string())?;
    }
    Ok(Records {
        src: Box::new(BufReader::with_capacity(1 << 20, file)),
        pos: 0,
        size: Some(size),
        complete,
        data_section_end,
    })
}

/// Streams the messages of the wanted topics in file order.
pub fn read(path: &Path, wanted: &[Wanted<'_>], visit: &mut Visitor<'_>) -> Result<Ended, String> {
    let mut records = open_records(path)?;
    let mut magic = [0u8; 8];
    let n = read_full(&mut records.src, &mut magic, 0)?;
    records.pos = n as u64;
    if magic[..n] != MAGIC[..n] || n == 0 {
        return Err("not an MCAP file (no MCAP magic at byte 0)".into());
    }
    let mut reader = Reader {
        wanted,
        visit,
        schemas: HashMap::new(),
        channels: HashMap::new(),
        last: (u16::MAX, None),
        last_log_time: None,
        messages: 0,
        zstd: None,
        chunk: Vec::new(),
        message: Vec::new(),
    };
    if n < 8 {
        return Ok(Ended {
            flow: Flow::Continue,
            note: Some(reader.cut_note(format!("the file ends at byte {n}, inside the magic"))),
        });
    }
    let mut body = Vec::new();
    loop {
        let (opcode, len, at) = match records.next()? {
            Next::Record { opcode, len, at } => (opcode, len, at),
            Next::End => {
                let note = format!(
                    "the file ends at byte {} without a data end record, summary or footer",
                    records.pos
                );
                return Ok(Ended {
                    flow: Flow::Continue,
                    note: Some(reader.cut_note(note)),
                });
            }
            Next::Cut(note) => {
                return Ok(Ended {
                    flow: Flow::Continue,
                    note: Some(reader.cut_note(note)),
                })
            }
        };
        let needed = matches!(opcode, op::MESSAGE | op::SCHEMA | op::CHANNEL | op::CHUNK);
        if opcode == op::DATA_END || opcode == op::FOOTER {
            records.check_data_section_end(opcode, len, at)?;
            return Ok(Ended {
                flow: Flow::Continue,
                note: None,
            });
        }
        if needed && len > MAX_RECORD {
            return Err(format!(
                "the record at byte {at} (opcode {opcode:#04x}) claims {len} bytes: more than the limit of {MAX_RECORD}"
            ));
        }
        let whole = if needed {
            records.body(len, &mut body)?
        } else {
            records.skip(len)?
        };
        if !whole {
            let (flow, note) = if opcode == op::CHUNK {
                reader.partial_chunk(&body, at, len, records.pos)?
            } else {
                let note = format!(
                    "the file ends at byte {} inside the record at byte {at} (opcode {opcode:#04x}, {len} bytes)",
                    records.pos
                );
                (Flow::Continue, note)
            };
            return Ok(Ended {
                flow,
                note: (flow == Flow::Continue).then(|| reader.cut_note(note)),
            });
        }
        if needed && reader.record(opcode, &body, At::File(at))? == Flow::Stop {
            return Ok(Ended {
                flow: Flow::Stop,
                note: None,
            });
        }
    }
}

/// The topics listed in the file's summary (type names as recorded); `None` without a summary
/// (a cut file, a `.mcap.zstd` stream, a writer that wrote none).
pub fn topics(path: &Path) -> Result<Option<Vec<TopicInfo>>, String> {
    if compression::is_zstd_file(path) {
        return Ok(None);
    }
    let mut file = File::open(path).map_err(|e| format!("cannot open: {e}"))?;
    let size = file.metadata().map_err(|e| e.to_string())?.len();
    if size < 8 + FOOTER_LEN + 8 {
        return Ok(None);
    }
    let footer_at = size - 8 - FOOTER_LEN;
    let mut tail = [0u8; (FOOTER_LEN + 8) as usize];
    file.seek(SeekFrom::Start(footer_at))
        .map_err(|e| e.to_string())?;
    if read_full(&mut file, &mut tail, footer_at)? != tail.len()
        || &tail[FOOTER_LEN as usize..] != MAGIC
    {
        return Ok(None);
    }
    let mut f = Fields {
        data: &tail[..FOOTER_LEN as usize],
        pos: 0,
    };
    let bad_footer = || format!("the footer at byte {footer_at} is malformed");
    if f.take(1, "footer")? != [op::FOOTER] || f.u64("footer length")? != 20 {
        return Err(bad_footer());
    }
    let summary_start = f.u64("summary start")?;
    if summary_start == 0 {
        return Ok(None);
    }
    if !(8..=footer_at).contains(&summary_start) {
        return Err(format!(
            "{}: the summary starts at byte {summary_start}, outside 8..{footer_at}",
            bad_footer()
        ));
    }
    file.seek(SeekFrom::Start(summary_start))
        .map_err(|e| e.to_string())?;
    let mut records = Records {
        src: BufReader::new(file.take(footer_at - summary_start)),
        pos: summary_start,
        size: Some(footer_at),
        complete: true,
        data_section_end: None,
    };
    let mut schemas: HashMap<u16, String> = HashMap::new();
    let mut channels: Vec<(u16, u16, String)> = Vec::new();
    let mut counts: Option<HashMap<u16, u64>> = None;
    let mut body = Vec::new();
    loop {
        let (opcode, len, at) = match records.next()? {
            Next::Record { opcode, len, at } => (opcode, len, at),
            Next::End => break,
            Next::Cut(note) => return Err(note),
        };
        if !matches!(opcode, op::SCHEMA | op::CHANNEL | op::STATISTICS) {
            records.skip(len)?;
            continue;
        }
        if len > MAX_RECORD {
            return Err(format!("the record at byte {at} claims {len} bytes"));
        }
        records.body(len, &mut body)?;
        let mut f = Fields {
            data: &body,
            pos: 0,
        };
        let parsed: Result<(), String> = (|| {
            match opcode {
                op::SCHEMA => {
                    let id = f.u16("schema id")?;
                    schemas.insert(id, f.string("schema name")?.to_string());
                }
                op::CHANNEL => {
                    let id = f.u16("channel id")?;
                    let schema = f.u16("channel schema id")?;
                    channels.push((id, schema, f.string("channel topic")?.to_string()));
                }
                _ => {
                    f.take(8 + 2 + 4 + 4 + 4 + 4 + 8 + 8, "statistics")?;
                    let map = f.bytes32("channel message counts")?;
                    let mut m = Fields { data: map, pos: 0 };
                    let mut c = HashMap::new();
                    while m.pos < map.len() {
                        let id = m.u16("channel message counts")?;
                        c.insert(id, m.u64("channel message counts")?);
                    }
                    counts = Some(c);
                }
            }
            Ok(())
        })();
        parsed.map_err(|e| format!("{}: {e}", At::File(at)))?;
    }
    channels.sort_by_key(|c| c.0);
    let mut topics: Vec<TopicInfo> = Vec::new();
    for (id, schema, topic) in channels {
        let count = counts.as_ref().map(|m| m.get(&id).copied().unwrap_or(0));
        match topics.iter_mut().find(|t| t.name == topic) {
            Some(t) => {
                // Counts are the file's word: a sum past u64 is a malformed statistics record.
                t.count = match t.count.zip(count) {
                    Some((a, b)) => Some(a.checked_add(b).ok_or_else(|| {
                        format!(
                            "the statistics record's message counts of topic '{}' overflow",
                            t.name
                        )
                    })?),
                    None => None,
                };
            }
            None => topics.push(TopicInfo {
                name: topic,
                type_name: schemas.get(&schema).cloned().unwrap_or_default(),
                count,
            }),
        }
    }
    Ok(Some(topics))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bag::cdr;
    use crate::bag::mcap_writer::{
        tests::{write_chunked, write_file},
        Compression,
    };
    use std::path::PathBuf;

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("sd_mcap_reader_{}_{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    const A: [Wanted<'static>; 2] = [
        Wanted {
            topic: "/a",
            type_name: "std_msgs/msg/String",
        },
        Wanted {
            topic: "/b",
            type_name: "std_msgs/msg/String",
        },
    ];

    /// Every message of both topics: `(log time, text)`, the note if the file was cut.
    type Messages = Vec<(u64, String)>;

    fn read_all(path: &Path) -> Result<(Messages, Option<String>), String> {
        let mut got = Vec::new();
        let ended = read(path, &A, &mut |m| {
            got.push((m.log_time, cdr::parse_string(m.data)?.to_string()));
            Ok(Flow::Continue)
        })?;
        Ok((got, ended.note))
    }

    /// `(opcode, start, end)` of the top-level records of a well-formed file.
    fn record_starts(bytes: &[u8]) -> Vec<(u8, usize, usize)> {
        let mut out = Vec::new();
        let mut at = 8;
        while at + 9 <= bytes.len() {
            let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
            out.push((bytes[at], at, at + 9 + len));
            at += 9 + len;
        }
        out
    }

    /// An unchunked file by the `mcap` crate's writer (an independent one): schema, channel,
    /// then one Message record per message, each `(log time, bytes)`.
    fn write_unchunked(path: &Path, n: u32) -> Vec<(u64, String)> {
        let file = std::io::BufWriter::new(File::create(path).unwrap());
        let mut w = mcap::WriteOptions::new()
            .use_chunks(false)
            .profile("ros2")
            .create(file)
            .unwrap();
        let schema = w
            .add_schema("std_msgs/msg/String", "ros2msg", b"string data")
            .unwrap();
        let channel = w
            .add_channel(schema, "/a", "cdr", &Default::default())
            .unwrap();
        let mut expected = Vec::new();
        for i in 0..n {
            let text = format!("m{i}");
            let mut data = Vec::new();
            cdr::write_string_msg(&mut data, &text);
            let header = mcap::records::MessageHeader {
                channel_id: channel,
                sequence: i,
                log_time: 100 + u64::from(i),
                publish_time: 100 + u64::from(i),
            };
            w.write_to_known_channel(&header, &data).unwrap();
            expected.push((100 + u64::from(i), text));
        }
        w.finish().unwrap();
        expected
    }

    /// One damaged byte that turns a message's opcode into a data end's or a footer's is an
    /// error naming its byte, not the quiet end of the data section.
    #[test]
    fn a_damaged_opcode_does_not_end_the_data_section_early() {
        let dir = scratch("early_end");
        let path = dir.join("whole.mcap");
        write_unchunked(&path, 50);
        let bytes = std::fs::read(&path).unwrap();
        let message = record_starts(&bytes)
            .into_iter()
            .filter(|r| r.0 == op::MESSAGE)
            .nth(20)
            .unwrap();
        for opcode in [op::DATA_END, op::FOOTER] {
            let mut damaged = bytes.clone();
            damaged[message.1] = opcode;
            let damaged_path = dir.join("damaged.mcap");
            std::fs::write(&damaged_path, &damaged).unwrap();
            let err = read_all(&damaged_path).unwrap_err();
            assert!(
                err.contains(&format!("the record at byte {}", message.1))
                    && err.contains("damaged"),
                "{err}"
            );
        }
        // A data end of the right length in the wrong place: named too.
        let data_end = record_starts(&bytes)
            .into_iter()
            .find(|r| r.0 == op::DATA_END)
            .unwrap();
        let mut early = bytes[..message.1].to_vec();
        early.extend_from_slice(&bytes[data_end.1..]);
        let early_path = dir.join("early.mcap");
        std::fs::write(&early_path, &early).unwrap();
        let err = read_all(&early_path).unwrap_err();
        assert!(err.contains("the footer says it ends at byte"), "{err}");
    }

    /// Cut anywhere (a killed recorder), a file gives a prefix of its messages and a note
    /// naming the byte where it ends, or everything and no note once the data end is in.
    #[test]
    fn cut_files_give_every_complete_message_before_the_cut() {
        let dir = scratch("cut");
        let path = dir.join("whole.mcap");
        let expected = write_unchunked(&path, 300);
        let bytes = std::fs::read(&path).unwrap();
        let (all, note) = read_all(&path).unwrap();
        assert_eq!(all, expected);
        assert!(note.is_none());
        let cut_path = dir.join("cut.mcap");
        // Message records of this file: where each ends; where the data end record ends.
        let records = record_starts(&bytes);
        let ends: Vec<usize> = records
            .iter()
            .filter(|r| r.0 == op::MESSAGE)
            .map(|r| r.2)
            .collect();
        let data_end = records.iter().find(|r| r.0 == op::DATA_END).unwrap().2;
        assert_eq!(ends.len(), 300);
        for cut in (9..bytes.len())
            .step_by(7)
            .chain([ends[150], ends[150] + 1, ends[299]])
        {
            std::fs::write(&cut_path, &bytes[..cut]).unwrap();
            let (got, note) = read_all(&cut_path).unwrap();
            let complete = ends.iter().filter(|&&e| e <= cut).count();
            assert_eq!(got, expected[..complete], "cut at {cut}");
            assert_eq!(note.is_some(), cut < data_end, "cut at {cut}: {note:?}");
            if cut < data_end {
                let note = note.unwrap_or_else(|| panic!("no note at {cut}"));
                if cut > ends[0] && cut < ends[299] {
                    assert!(note.contains(&format!("ends at byte {cut}")), "{note}");
                    let last = expected[complete - 1].0;
                    assert!(note.contains(&format!("log time 0.{last:09} s")), "{note}");
                }
            }
        }
        // Chunked (several chunks): a prefix of the messages, growing with the cut (inside a
        // chunk: `a_cut_chunk_gives_its_records_complete_before_the_cut`).
        let chunked = dir.join("chunked.mcap");
        let expected = write_file(&chunked, Compression::Zstd(1));
        let bytes = std::fs::read(&chunked).unwrap();
        let mut before = 0;
        for cut in (9..bytes.len()).step_by(97) {
            std::fs::write(&cut_path, &bytes[..cut]).unwrap();
            let (got, _) = read_all(&cut_path).unwrap();
            assert!(got.len() >= before, "{cut}");
            before = got.len();
            let want: Vec<_> = expected[..got.len()]
                .iter()
                .map(|e| (e.1, e.2.clone()))
                .collect();
            assert_eq!(got, want);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The uncompressed bytes each block of a compressed chunk's frame holds, with where the
    /// block ends in the frame: `(end in the frame, uncompressed bytes)`, read from the frame
    /// format (zstd RFC 8878, the lz4 frame format) rather than from a decoder. A compressed
    /// block's own size is not in its header: every block but the last holds the frame's full
    /// block size (asserted by the sizes adding up to the chunk's `total`).
    fn frame_blocks(compression: Compression, frame: &[u8], total: usize) -> Vec<(usize, usize)> {
        let mut blocks = Vec::new();
        let u32_at = |at: usize| u32::from_le_bytes(frame[at..at + 4].try_into().unwrap());
        let full;
        match compression {
            Compression::Lz4 => {
                assert_eq!(u32_at(0), 0x184D_2204);
                let (flg, bd) = (frame[4], frame[5]);
                full = 1usize << (8 + 2 * ((bd >> 4) & 7));
                let mut at = 6 + if flg & 0x08 != 0 { 8 } else { 0 } + usize::from(flg & 1) * 4 + 1;
                loop {
                    let word = u32_at(at);
                    if word == 0 {
                        break;
                    }
                    let size = (word & 0x7fff_ffff) as usize;
                    at += 4 + size + if flg & 0x10 != 0 { 4 } else { 0 };
                    let stored = word & 0x8000_0000 != 0;
                    blocks.push((at, if stored { size } else { full }));
                }
            }
            Compression::Zstd(_) => {
                assert_eq!(frame[..4], compression::ZSTD_MAGIC);
                let fhd = frame[4];
                let single = fhd & 0x20 != 0;
                let fcs = [usize::from(single), 2, 4, 8][usize::from(fhd >> 6)];
                let dict = [0, 1, 2, 4][usize::from(fhd & 3)];
                let mut at = 5 + usize::from(!single) + dict + fcs;
                full = if single {
                    total
                } else {
                    1usize << (10 + (frame[5] >> 3))
                }
                .min(128 << 10);
                loop {
                    let h = frame[at] as usize
                        | (frame[at + 1] as usize) << 8
                        | (frame[at + 2] as usize) << 16;
                    let (last, kind, size) = (h & 1 == 1, (h >> 1) & 3, h >> 3);
                    at += 3 + if kind == 1 { 1 } else { size };
                    blocks.push((at, if kind == 2 { full } else { size }));
                    if last {
                        break;
                    }
                }
            }
            Compression::None => unreachable!("an uncompressed chunk has no blocks"),
        }
        // The last block holds the rest.
        let before: usize = blocks[..blocks.len() - 1].iter().map(|b| b.1).sum();
        let last = blocks.last_mut().unwrap();
        assert!(
            before < total && total - before <= full,
            "{before} {total} {full}"
        );
        last.1 = total - before;
        assert!(
            blocks.len() > 2,
            "{} blocks: too few to cut between",
            blocks.len()
        );
        blocks
    }

    /// A file cut inside its one chunk (uncompressed, lz4, zstd) gives exactly the messages
    /// whose records are complete in the bytes before the cut: for an uncompressed chunk, the
    /// records ending by the cut; for a compressed one, the records ending within the blocks of
    /// the frame complete before the cut (what a decoder can produce: a compressed block comes
    /// out only whole, and these blocks are all compressed). The note names the cut's byte, the
    /// messages recovered, the last log time and the unchecked CRC. The cuts: every byte of the
    /// chunk's first 600 (header and first records), each byte around the end of a block or a
    /// message record, and every 131st byte.
    #[test]
    fn a_cut_chunk_gives_its_records_complete_before_the_cut() {
        let dir = scratch("cut_chunk");
        let path = dir.join("whole.mcap");
        let cut_path = dir.join("cut.mcap");
        for compression in [Compression::None, Compression::Lz4, Compression::Zstd(1)] {
            let expected = write_chunked(&path, compression, 7000, 7000);
            let bytes = std::fs::read(&path).unwrap();
            let (_, chunk, chunk_end) = *record_starts(&bytes)
                .iter()
                .find(|r| r.0 == op::CHUNK)
                .unwrap();
            // Chunk body: start, end, uncompressed size, crc, compression, records length.
            let size = u64::from_le_bytes(bytes[chunk + 25..chunk + 33].try_into().unwrap());
            let name =
                u32::from_le_bytes(bytes[chunk + 37..chunk + 41].try_into().unwrap()) as usize;
            let records_at = chunk + 41 + name + 8;
            let frame = &bytes[records_at..chunk_end];
            let plain = match compression {
                Compression::None => frame.to_vec(),
                _ => {
                    let mut out = Vec::new();
                    match compression {
                        Compression::Lz4 => lz4::Decoder::new(frame)
                            .unwrap()
                            .read_to_end(&mut out)
                            .unwrap(),
                        _ => zstd::stream::read::Decoder::new(frame)
                            .unwrap()
                            .read_to_end(&mut out)
                            .unwrap(),
                    };
                    out
                }
            };
            assert_eq!(plain.len() as u64, size);
            // Where each message record ends in the chunk's records (all are messages).
            let mut ends = Vec::new();
            let mut at = 0;
            while at < plain.len() {
                assert_eq!(plain[at], op::MESSAGE);
                at += 9 + u64::from_le_bytes(plain[at + 1..at + 9].try_into().unwrap()) as usize;
                ends.push(at);
            }
            assert_eq!(ends.len(), expected.len());
            let blocks = match compression {
                Compression::None => Vec::new(),
                _ => frame_blocks(compression, frame, plain.len()),
            };
            // Plain bytes a cut at file byte `cut` leaves whole.
            let whole = |cut: usize| -> usize {
                let present = cut.saturating_sub(records_at);
                match compression {
                    Compression::None => present,
                    _ => blocks.iter().filter(|b| b.0 <= present).map(|b| b.1).sum(),
                }
            };
            let near = |e: usize| [e - 1, e, e + 1];
            let mut cuts: Vec<usize> = (chunk + 9..chunk + 600)
                .chain((chunk + 9..chunk_end).step_by(131))
                .chain(blocks.iter().flat_map(|b| near(records_at + b.0)))
                .collect();
            if compression == Compression::None {
                cuts.extend(ends.iter().step_by(97).flat_map(|&e| near(records_at + e)));
            }
            cuts.retain(|&c| c > chunk + 9 && c < chunk_end);
            cuts.sort_unstable();
            cuts.dedup();
            let mut recovered_some = 0;
            for cut in cuts {
                std::fs::write(&cut_path, &bytes[..cut]).unwrap();
                let (got, note) = read_all(&cut_path).unwrap();
                let k = ends.iter().filter(|&&e| e <= whole(cut)).count();
                let want: Vec<_> = expected[..k].iter().map(|e| (e.1, e.2.clone())).collect();
                assert_eq!(got, want, "{compression:?} cut at {cut}");
                let note = note.unwrap();
                assert!(
                    note.contains(&format!(
                        "ends at byte {cut} inside the chunk at byte {chunk}"
                    )),
                    "{note}"
                );
                if cut >= records_at {
                    assert!(note.contains(&format!("recovered {k} messages")), "{note}");
                    assert!(note.contains("CRC unchecked"), "{note}");
                }
                match k {
                    0 => assert!(note.contains("no complete message before it"), "{note}"),
                    _ => {
                        let t = expected[k - 1].1;
                        recovered_some += 1;
                        assert!(note.contains(&format!("log time 0.{t:09} s")), "{note}");
                    }
                }
            }
            assert!(recovered_some > 100, "{compression:?}: {recovered_some}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Damage is an error naming the byte, never a panic or an allocation of the size claimed:
    /// a record length set huge (in a complete file, and inside a chunk), and thousands of
    /// random byte changes.
    #[test]
    fn damaged_files_are_errors_not_crashes() {
        let dir = scratch("damaged");
        let path = dir.join("whole.mcap");
        write_unchunked(&path, 50);
        let bytes = std::fs::read(&path).unwrap();
        let bad = dir.join("bad.mcap");
        // The first message record's length, set to 2^62 (the file still ends with the magic).
        let first = record_starts(&bytes)
            .iter()
            .find(|r| r.0 == op::MESSAGE)
            .unwrap()
            .1;
        let mut b = bytes.clone();
        b[first + 1..first + 9].copy_from_slice(&(1u64 << 62).to_le_bytes());
        std::fs::write(&bad, &b).unwrap();
        let err = read_all(&bad).unwrap_err();
        assert!(
            err.contains(&format!("record at byte {first}")) && err.contains("claims"),
            "{err}"
        );
        // Inside a (compressed) chunk: the chunk's CRC catches it first; without the CRC the
        // length check does.
        let chunked = dir.join("chunked.mcap");
        write_file(&chunked, Compression::None);
        let c = std::fs::read(&chunked).unwrap();
        let chunk = record_starts(&c)
            .iter()
            .find(|r| r.0 == op::CHUNK)
            .unwrap()
            .1;
        // Chunk body: 8 + 8 + 8 + crc 4 + compression "" (4) + records length 8, then records.
        let crc_at = chunk + 9 + 24;
        let records = crc_at + 4 + 4 + 8;
        let mut d = c.clone();
        d[records + 1 + 3] ^= 0x40;
        std::fs::write(&bad, &d).unwrap();
        assert!(read_all(&bad).unwrap_err().contains("CRC"));
        d[crc_at..crc_at + 4].copy_from_slice(&[0; 4]);
        std::fs::write(&bad, &d).unwrap();
        let err = read_all(&bad).unwrap_err();
        assert!(
            err.contains(&format!("chunk at byte {chunk}")) && err.contains("claims"),
            "{err}"
        );

        // Random single-byte changes, and random 8-byte lengths written over record lengths.
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rand = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for (k, source) in [&bytes, &c].into_iter().enumerate() {
            for _ in 0..1500 {
                let mut m = source.clone();
                let i = (rand() % m.len() as u64) as usize;
                if rand() % 2 == 0 {
                    m[i] = rand() as u8;
                } else if i + 8 <= m.len() {
                    m[i..i + 8].copy_from_slice(&rand().to_le_bytes());
                }
                if rand() % 4 == 0 {
                    m.truncate((rand() % m.len() as u64) as usize);
                }
                let file = dir.join(format!("m{k}.mcap"));
                std::fs::write(&file, &m).unwrap();
                let _ = read_all(&file);
                let _ = topics(&file);
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn summary_topics_match_what_was_written() {
        let dir = scratch("summary");
        let path = dir.join("f.mcap");
        write_file(&path, Compression::Lz4);
        let listed = topics(&path).unwrap().unwrap();
        let got: Vec<_> = listed
            .iter()
            .map(|t| (t.name.as_str(), t.type_name.as_str(), t.count))
            .collect();
        assert_eq!(
            got,
            [
                ("/a", "std_msgs/msg/String", Some(3333)),
                ("/b", "std_msgs/msg/String", Some(1667))
            ]
        );
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
        assert!(topics(&path).unwrap().is_none());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
