//! MCAP files written in the ROS 2 profile: chunks built and compressed by the replay's
//! workers ([`ChunkBuilder`]), appended with their indexes, then a summary and footer
//! ([`McapWriter`]). Reading is `mcap_reader`'s.

use mcap::records::op;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

/// Chunk compression of the written file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Compression {
    None,
    /// zstd at a level: 1 is what the MCAP C++ writer, and so rosbag2, calls the default;
    /// negative levels (zstd's `--fast=N`) trade a few percent of size for speed.
    Zstd(i32),
    /// LZ4 frames.
    Lz4,
}

impl Compression {
    fn name(self) -> &'static str {
        match self {
            Compression::None => "",
            Compression::Zstd(_) => "zstd",
            Compression::Lz4 => "lz4",
        }
    }
}

// MCAP records: opcode, u64 length, fields little-endian; strings and byte arrays with a u32
// length; maps with a u32 byte length.

fn put_u16(out: &mut Vec<u8>, x: u16) {
    out.extend_from_slice(&x.to_le_bytes());
}
fn put_u32(out: &mut Vec<u8>, x: u32) {
    out.extend_from_slice(&x.to_le_bytes());
}
fn put_u64(out: &mut Vec<u8>, x: u64) {
    out.extend_from_slice(&x.to_le_bytes());
}
fn put_str(out: &mut Vec<u8>, s: &str) {
    put_u32(out, s.len() as u32);
    out.extend_from_slice(s.as_bytes());
}

/// Starts a record; [`end_record`] writes its length.
fn begin_record(out: &mut Vec<u8>, opcode: u8) -> usize {
    out.push(opcode);
    put_u64(out, 0);
    out.len()
}
fn end_record(out: &mut [u8], body_start: usize) {
    let len = (out.len() - body_start) as u64;
    out[body_start - 8..body_start].copy_from_slice(&len.to_le_bytes());
}
/// Starts a map (or an array with a byte length); [`end_map`] writes its length.
fn begin_map(out: &mut Vec<u8>) -> usize {
    put_u32(out, 0);
    out.len()
}
fn end_map(out: &mut [u8], start: usize) {
    let len = (out.len() - start) as u32;
    out[start - 4..start].copy_from_slice(&len.to_le_bytes());
}

/// One chunk being filled with messages, then compressed with its message indexes: the work
/// of one replay worker, so that chunks are compressed in parallel.
pub struct ChunkBuilder {
    compression: Compression,
    zstd: Option<zstd::bulk::Compressor<'static>>,
    /// Uncompressed Message records.
    records: Vec<u8>,
    message: usize,
    /// `(log_time, offset in records)` by channel id.
    index: Vec<Vec<(u64, u64)>>,
    start: u64,
    end: u64,
}

/// A chunk record followed by its message index records, ready to be appended to the file.
#[derive(Default)]
pub struct FinishedChunk {
    bytes: Vec<u8>,
    /// Length of the chunk record (the message indexes follow it).
    chunk_len: u64,
    /// `(channel id, offset in bytes)` of each message index record.
    index_offsets: Vec<(u16, u64)>,
    /// Messages by channel id.
    counts: Vec<u64>,
    start: u64,
    end: u64,
    compressed_size: u64,
    uncompressed_size: u64,
}

impl FinishedChunk {
    /// Number of messages on a channel in the chunk.
    pub fn count(&self, channel: u16) -> u64 {
        self.counts.get(channel as usize).copied().unwrap_or(0)
    }
}

impl ChunkBuilder {
    /// A builder for channels with ids below `channels`.
    pub fn new(compression: Compression, channels: u16) -> Result<ChunkBuilder, String> {
        let zstd = match compression {
            Compression::Zstd(level) => {
                Some(zstd::bulk::Compressor::new(level).map_err(|e| format!("zstd: {e}"))?)
            }
            _ => None,
        };
        Ok(ChunkBuilder {
            compression,
            zstd,
            records: Vec::new(),
            message: 0,
            index: vec![Vec::new(); channels as usize],
            start: u64::MAX,
            end: 0,
        })
    }

    /// Starts a message record (publish time = log time) and returns the buffer its data is
    /// appended to; [`end_message`](Self::end_message) closes it.
    pub fn begin_message(&mut self, channel: u16, sequence: u32, log_time: u64) -> &mut Vec<u8> {
        self.index[channel as usize].push((log_time, self.records.len() as u64));
        self.start = self.start.min(log_time);
        self.end = self.end.max(log_time);
        self.message = begin_record(&mut self.records, op::MESSAGE);
        put_u16(&mut self.records, channel);
        put_u32(&mut self.records, sequence);
        put_u64(&mut self.records, log_time);
        put_u64(&mut self.records, log_time);
        &mut self.records
    }

    /// Closes the message begun last.
    pub fn end_message(&mut self) {
        end_record(&mut self.records, self.message);
    }

    /// Compresses the messages into `out` (its buffers reused) and starts a new chunk.
    pub fn finish(&mut self, out: &mut FinishedChunk) -> Result<(), String> {
        let uncompressed_crc = crc32fast::hash(&self.records);
        out.bytes.clear();
        let body = begin_record(&mut out.bytes, op::CHUNK);
        put_u64(
            &mut out.bytes,
            if self.records.is_empty() {
                0
            } else {
                self.start
            },
        );
        put_u64(&mut out.bytes, self.end);
        put_u64(&mut out.bytes, self.records.len() as u64);
        put_u32(&mut out.bytes, uncompressed_crc);
        put_str(&mut out.bytes, self.compression.name());
        let size_at = out.bytes.len();
        put_u64(&mut out.bytes, 0);
        let data_start = out.bytes.len();
        match self.compression {
            Compression::None => out.bytes.extend_from_slice(&self.records),
            Compression::Zstd(_) => {
                // Straight into the spare capacity after the chunk's header (no zeroing, no
                // copy): a cursor at the end makes zstd append.
                out.bytes
                    .reserve(zstd::zstd_safe::compress_bound(self.records.len()));
                let mut at_end = std::io::Cursor::new(&mut out.bytes);
                at_end.set_position(data_start as u64);
                let zstd = self.zstd.as_mut().expect("a zstd compressor");
                zstd.compress_to_buffer(&self.records, &mut at_end)
                    .map_err(|e| format!("zstd: {e}"))?;
            }
            Compression::Lz4 => {
                let mut encoder = lz4::EncoderBuilder::new()
                    .block_checksum(lz4::liblz4::BlockChecksum::NoBlockChecksum)
                    .build(std::mem::take(&mut out.bytes))
                    .map_err(|e| format!("lz4: {e}"))?;
                std::io::Write::write_all(&mut encoder, &self.records)
                    .map_err(|e| format!("lz4: {e}"))?;
                let (bytes, result) = encoder.finish();
                result.map_err(|e| format!("lz4: {e}"))?;
                out.bytes = bytes;
            }
        }
        let compressed = (out.bytes.len() - data_start) as u64;
        out.bytes[size_at..size_at + 8].copy_from_slice(&compressed.to_le_bytes());
        end_record(&mut out.bytes, body);
        out.chunk_len = out.bytes.len() as u64;
        out.compressed_size = compressed;
        out.uncompressed_size = self.records.len() as u64;
        out.start = self.start;
        out.end = self.end;
        out.index_offsets.clear();
        out.counts.clear();
        for (channel, entries) in self.index.iter_mut().enumerate() {
            out.counts.push(entries.len() as u64);
            if entries.is_empty() {
                continue;
            }
            out.index_offsets
                .push((channel as u16, out.bytes.len() as u64));
            let body = begin_record(&mut out.bytes, op::MESSAGE_INDEX);
            put_u16(&mut out.bytes, channel as u16);
            let map = begin_map(&mut out.bytes);
            for &(log_time, offset) in entries.iter() {
                put_u64(&mut out.bytes, log_time);
                put_u64(&mut out.bytes, offset);
            }
            end_map(&mut out.bytes, map);
            end_record(&mut out.bytes, body);
            entries.clear();
        }
        self.records.clear();
        self.start = u64::MAX;
        self.end = 0;
        Ok(())
    }
}

/// An MCAP file being written, ROS 2 profile: schemas `ros2msg` (the concatenated message
/// definitions), messages `cdr`, channels carrying `offered_qos_profiles` as rosbag2 does;
/// chunked, indexed, with a summary (schemas, channels, statistics, chunk indexes) and CRCs.
/// Chunks come ready-made from [`ChunkBuilder`]s.
pub struct McapWriter {
    file: BufWriter<File>,
    path: std::path::PathBuf,
    compression: Compression,
    /// Bytes written so far, and their CRC (the data section's, up to the data end record).
    pos: u64,
    crc: crc32fast::Hasher,
    /// Schema and channel records, repeated in the summary.
    schemas: Vec<u8>,
    channels: Vec<u8>,
    channel_count: u16,
    chunk_indexes: Vec<u8>,
    chunk_count: u32,
    counts: Vec<u64>,
    start: u64,
    end: u64,
}

/// The QoS the node's outputs offer (reliable, volatile, keep last 10), in rosbag2's format.
const OUTPUT_QOS: &str = "- history: keep_last
  depth: 10
  reliability: reliable
  durability: volatile
  deadline:
    sec: 2147483647
    nsec: 4294967295
  lifespan:
    sec: 2147483647
    nsec: 4294967295
  liveliness: automatic
  liveliness_lease_duration:
    sec: 2147483647
    nsec: 4294967295
  avoid_ros_namespace_conventions: false
";

const MAGIC: &[u8] = b"\x89MCAP0\r\n";

impl McapWriter {
    /// Creates (or truncates) `path` and writes the header.
    pub fn create(path: &Path, compression: Compression) -> Result<Self, String> {
        let file =
            File::create(path).map_err(|e| format!("cannot create {}: {e}", path.display()))?;
        let mut w = McapWriter {
            file: BufWriter::with_capacity(1 << 20, file),
            path: path.to_path_buf(),
            compression,
            pos: 0,
            crc: crc32fast::Hasher::new(),
            schemas: Vec::new(),
            channels: Vec::new(),
            channel_count: 0,
            chunk_indexes: Vec::new(),
            chunk_count: 0,
            counts: Vec::new(),
            start: u64::MAX,
            end: 0,
        };
        let mut head = MAGIC.to_vec();
        let body = begin_record(&mut head, op::HEADER);
        put_str(&mut head, "ros2");
        put_str(
            &mut head,
            concat!("spatial_dynamics ", env!("CARGO_PKG_VERSION"), " replay"),
        );
        end_record(&mut head, body);
        w.put(&head)?;
        Ok(w)
    }

    fn put(&mut self, bytes: &[u8]) -> Result<(), String> {
        self.crc.update(bytes);
        self.pos += bytes.len() as u64;
        std::io::Write::write_all(&mut self.file, bytes)
            .map_err(|e| format!("cannot write {}: {e}", self.path.display()))
    }

    /// Adds a topic (a schema and a channel record); returns its channel id, for
    /// [`ChunkBuilder::begin_message`]. Ids start at 1.
    pub fn add_topic(
        &mut self,
        topic: &str,
        type_name: &str,
        definition: &str,
    ) -> Result<u16, String> {
        self.channel_count += 1;
        let id = self.channel_count;
        let mut records = Vec::new();
        let body = begin_record(&mut records, op::SCHEMA);
        put_u16(&mut records, id);
        put_str(&mut records, type_name);
        put_str(&mut records, "ros2msg");
        put_str(&mut records, definition);
        end_record(&mut records, body);
        let schema_len = records.len();
        let body = begin_record(&mut records, op::CHANNEL);
        put_u16(&mut records, id);
        put_u16(&mut records, id);
        put_str(&mut records, topic);
        put_str(&mut records, "cdr");
        let map = begin_map(&mut records);
        put_str(&mut records, "offered_qos_profiles");
        put_str(&mut records, OUTPUT_QOS);
        end_map(&mut records, map);
        end_record(&mut records, body);
        self.schemas.extend_from_slice(&records[..schema_len]);
        self.channels.extend_from_slice(&records[schema_len..]);
        self.counts.push(0);
        self.put(&records)?;
        Ok(id)
    }

    /// A chunk builder for this file's channels and compression.
    pub fn chunk_builder(&self) -> Result<ChunkBuilder, String> {
        ChunkBuilder::new(self.compression, self.channel_count + 1)
    }

    /// Appends a finished chunk (nothing for an empty one).
    pub fn write_chunk(&mut self, chunk: &FinishedChunk) -> Result<(), String> {
        if chunk.uncompressed_size == 0 {
            return Ok(());
        }
        let at = self.pos;
        self.put(&chunk.bytes)?;
        let mut index = std::mem::take(&mut self.chunk_indexes);
        let body = begin_record(&mut index, op::CHUNK_INDEX);
        put_u64(&mut index, chunk.start);
        put_u64(&mut index, chunk.end);
        put_u64(&mut index, at);
        put_u64(&mut index, chunk.chunk_len);
        let map = begin_map(&mut index);
        for &(channel, offset) in &chunk.index_offsets {
            put_u16(&mut index, channel);
            put_u64(&mut index, at + offset);
        }
        end_map(&mut index, map);
        put_u64(&mut index, chunk.bytes.len() as u64 - chunk.chunk_len);
        put_str(&mut index, self.compression.name());
        put_u64(&mut index, chunk.compressed_size);
        put_u64(&mut index, chunk.uncompressed_size);
        end_record(&mut index, body);
        self.chunk_indexes = index;
        self.chunk_count += 1;
        for (k, n) in chunk.counts.iter().enumerate().skip(1) {
            self.counts[k - 1] += n;
        }
        self.start = self.start.min(chunk.start);
        self.end = self.end.max(chunk.end);
        Ok(())
    }

    /// Writes the data end, the summary and the footer, and closes the file.
    pub fn finish(mut self) -> Result<(), String> {
        let mut tail = Vec::new();
        let body = begin_record(&mut tail, op::DATA_END);
        put_u32(&mut tail, self.crc.clone().finalize());
        end_record(&mut tail, body);
        let summary_start = self.pos + tail.len() as u64;
        let mut summary = Vec::new();
        let mut groups = Vec::new();
        let stats = self.statistics();
        let chunk_indexes = std::mem::take(&mut self.chunk_indexes);
        for (opcode, records) in [
            (op::SCHEMA, &self.schemas),
            (op::CHANNEL, &self.channels),
            (op::STATISTICS, &stats),
            (op::CHUNK_INDEX, &chunk_indexes),
        ] {
            if !records.is_empty() {
                groups.push((
                    opcode,
                    summary_start + summary.len() as u64,
                    records.len() as u64,
                ));
                summary.extend_from_slice(records);
            }
        }
        let offsets_start = summary_start + summary.len() as u64;
        for (opcode, start, len) in groups {
            let body = begin_record(&mut summary, op::SUMMARY_OFFSET);
            summary.push(opcode);
            put_u64(&mut summary, start);
            put_u64(&mut summary, len);
            end_record(&mut summary, body);
        }
        // The footer's CRC covers the summary and the footer up to itself, its length included.
        summary.push(op::FOOTER);
        put_u64(&mut summary, 8 + 8 + 4);
        put_u64(&mut summary, summary_start);
        put_u64(&mut summary, offsets_start);
        let crc = crc32fast::hash(&summary);
        put_u32(&mut summary, crc);
        summary.extend_from_slice(MAGIC);
        tail.extend_from_slice(&summary);
        self.put(&tail)?;
        std::io::Write::flush(&mut self.file)
            .map_err(|e| format!("cannot write {}: {e}", self.path.display()))
    }

    fn statistics(&self) -> Vec<u8> {
        let mut out = Vec::new();
        let body = begin_record(&mut out, op::STATISTICS);
        put_u64(&mut out, self.counts.iter().sum());
        put_u16(&mut out, self.channel_count);
        put_u32(&mut out, u32::from(self.channel_count));
        put_u32(&mut out, 0);
        put_u32(&mut out, 0);
        put_u32(&mut out, self.chunk_count);
        put_u64(&mut out, if self.chunk_count == 0 { 0 } else { self.start });
        put_u64(&mut out, self.end);
        let map = begin_map(&mut out);
        for (k, &n) in self.counts.iter().enumerate() {
            put_u16(&mut out, k as u16 + 1);
            put_u64(&mut out, n);
        }
        end_map(&mut out, map);
        end_record(&mut out, body);
        out
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::bag::{cdr, Bag, Flow, Storage, Wanted};
    use mcap::records::Record;
    use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
    use std::io::Read;

    /// Writes 5000 string messages on two topics in chunks of 700, each message's log time
    /// `1000 + 7 i`; returns the expected `(topic, log time, text)` in order.
    pub(in crate::bag) fn write_file(
        path: &Path,
        compression: Compression,
    ) -> Vec<(String, u64, String)> {
        write_chunked(path, compression, 5000, 700)
    }

    /// Writes `n` string messages `message i` on two topics (`/b` every third) in chunks of
    /// `per_chunk`, each message's log time `1000 + 7 i`; returns the expected
    /// `(topic, log time, text)` in order.
    pub(in crate::bag) fn write_chunked(
        path: &Path,
        compression: Compression,
        n: u32,
        per_chunk: u32,
    ) -> Vec<(String, u64, String)> {
        let mut w = McapWriter::create(path, compression).unwrap();
        let a = w
            .add_topic("/a", "std_msgs/msg/String", "string data\n")
            .unwrap();
        let b = w
            .add_topic("/b", "std_msgs/msg/String", "string data\n")
            .unwrap();
        let mut builder = w.chunk_builder().unwrap();
        let mut chunk = FinishedChunk::default();
        let mut expected = Vec::new();
        for i in 0..n {
            let (channel, topic) = if i % 3 == 0 { (b, "/b") } else { (a, "/a") };
            let log_time = 1_000 + 7 * u64::from(i);
            let text = format!("message {i}");
            cdr::write_string_msg(builder.begin_message(channel, i, log_time), &text);
            builder.end_message();
            expected.push((topic.to_string(), log_time, text));
            if i % per_chunk == per_chunk - 1 {
                builder.finish(&mut chunk).unwrap();
                w.write_chunk(&chunk).unwrap();
            }
        }
        builder.finish(&mut chunk).unwrap();
        w.write_chunk(&chunk).unwrap();
        builder.finish(&mut chunk).unwrap(); // an empty chunk is not written
        w.write_chunk(&chunk).unwrap();
        w.finish().unwrap();
        expected
    }

    /// Files written here, with each compression, are read by the `mcap` crate (an independent
    /// reader) with every CRC checked, linearly and through the summary's indexes, and by ours.
    #[test]
    fn written_files_are_valid_mcap_with_every_chunk_compression() {
        let dir = std::env::temp_dir().join(format!("sd_mcap_test_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (compression, name) in [
            (Compression::None, "none"),
            (Compression::Zstd(1), "zstd"),
            (Compression::Zstd(-2), "zstd-fast"),
            (Compression::Lz4, "lz4"),
        ] {
            let path = dir.join(format!("{name}.mcap"));
            let expected = write_file(&path, compression);
            let bytes = std::fs::read(&path).unwrap();

            // Linear, every record and CRC checked.
            let mut reader = LinearReader::new_with_options(
                LinearReaderOptions::default()
                    .with_validate_chunk_crcs(true)
                    .with_validate_data_section_crc(true)
                    .with_validate_summary_section_crc(true)
                    .with_check_finishes_after_end_magic(true),
            );
            let mut source = std::io::Cursor::new(&bytes);
            let mut header = None;
            while let Some(event) = reader.next_event() {
                match event.unwrap() {
                    LinearReadEvent::ReadRequest(n) => {
                        let read = source.read(reader.insert(n)).unwrap();
                        reader.notify_read(read);
                    }
                    LinearReadEvent::Record { opcode, data } => {
                        if let Record::Header(h) = mcap::parse_record(opcode, data).unwrap() {
                            header = Some(h);
                        }
                    }
                }
            }
            let header = header.unwrap();
            assert_eq!(header.profile, "ros2");
            let options = mcap::read::Options::ValidateChunkCrcs.into();
            let got: Vec<(String, u64, String)> =
                mcap::MessageStream::new_with_options(&bytes, options)
                    .unwrap()
                    .map(|m| {
                        let m = m.unwrap();
                        assert_eq!(m.channel.message_encoding, "cdr");
                        assert_eq!(m.channel.schema.as_ref().unwrap().encoding, "ros2msg");
                        assert_eq!(m.publish_time, m.log_time);
                        let text = cdr::parse_string(&m.data).unwrap().to_string();
                        (m.channel.topic.clone(), m.log_time, text)
                    })
                    .collect();
            assert_eq!(got, expected, "{name}");

            // Through the summary: statistics, chunk indexes and message indexes.
            let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
            let stats = summary.stats.as_ref().unwrap();
            assert_eq!(stats.message_count, 5000);
            assert_eq!(stats.chunk_count, 8);
            assert_eq!(
                (stats.message_start_time, stats.message_end_time),
                (1_000, 1_000 + 7 * 4999)
            );
            assert_eq!(
                stats
                    .channel_message_counts
                    .values()
                    .copied()
                    .collect::<Vec<_>>(),
                [3333, 1667]
            );
            let mut indexed = Vec::new();
            for chunk in &summary.chunk_indexes {
                assert_eq!(chunk.compression, compression.name());
                for (channel, entries) in summary.read_message_indexes(&bytes, chunk).unwrap() {
                    for entry in entries {
                        let m = summary.seek_message(&bytes, chunk, &entry).unwrap();
                        assert_eq!(m.channel.id, channel.id);
                        assert_eq!(m.log_time, entry.log_time);
                        indexed.push(m.log_time);
                    }
                }
            }
            indexed.sort();
            assert_eq!(indexed, expected.iter().map(|e| e.1).collect::<Vec<_>>());

            // Ours: one topic, in order; a wrong type refused.
            let bag = Bag::open(&path, &Default::default()).unwrap();
            assert_eq!(bag.storage, Storage::Mcap);
            let topics = bag.topics().unwrap().unwrap();
            assert_eq!(topics[0].count, Some(3333));
            let mut ours = Vec::new();
            let wanted = [Wanted {
                topic: "/a",
                type_name: "std_msgs/msg/String",
            }];
            bag.read(&wanted, &mut |m| {
                ours.push((m.log_time, cdr::parse_string(m.data)?.to_string()));
                Ok(Flow::Continue)
            })
            .unwrap();
            let only_a: Vec<_> = expected
                .iter()
                .filter(|e| e.0 == "/a")
                .map(|e| (e.1, e.2.clone()))
                .collect();
            assert_eq!(ours, only_a, "{name}");
            let wrong = [Wanted {
                topic: "/b",
                type_name: "sensor_msgs/msg/JointState",
            }];
            let err = bag.read(&wrong, &mut |_| Ok(Flow::Continue)).unwrap_err();
            assert!(
                err.contains("topic /b has type std_msgs/msg/String"),
                "{err}"
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
