//! MCAP files: streamed with the `mcap` crate's sans-io reader (chunks uncompressed, zstd or
//! lz4; memory bounded by the largest chunk), and written with its writer in the ROS 2 profile.

use super::{match_topic, Flow, RawMessage, TopicInfo, Visitor, Wanted};
use mcap::records::{op, Record};
use mcap::sans_io::{LinearReadEvent, LinearReader, SummaryReadEvent, SummaryReader};
use mcap::sans_io::{LinearReaderOptions, SummaryReaderOptions};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Read, Seek};
use std::path::Path;

fn open(path: &Path) -> Result<File, String> {
    File::open(path).map_err(|e| format!("cannot open: {e}"))
}

/// The topics listed in the file's summary; `None` without a summary.
pub fn topics(path: &Path) -> Result<Option<Vec<TopicInfo>>, String> {
    let mut file = open(path)?;
    let size = file.metadata().map_err(|e| e.to_string())?.len();
    let mut reader =
        SummaryReader::new_with_options(SummaryReaderOptions::default().with_file_size(size));
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| format!("{}: {e}", path.display()))? {
            SummaryReadEvent::ReadRequest(n) => {
                let read = file.read(reader.insert(n)).map_err(|e| e.to_string())?;
                reader.notify_read(read);
            }
            SummaryReadEvent::SeekRequest(to) => {
                let pos = file.seek(to).map_err(|e| e.to_string())?;
                reader.notify_seeked(pos);
            }
        }
    }
    let Some(summary) = reader.finish() else {
        return Ok(None);
    };
    let counts = summary
        .stats
        .as_ref()
        .map(|s| s.channel_message_counts.clone());
    let mut channels: Vec<_> = summary.channels.values().collect();
    channels.sort_by_key(|c| c.id);
    let mut topics: Vec<TopicInfo> = Vec::new();
    for c in channels {
        let count = counts.as_ref().map(|m| m.get(&c.id).copied().unwrap_or(0));
        match topics.iter_mut().find(|t| t.name == c.topic) {
            Some(t) => t.count = t.count.zip(count).map(|(a, b)| a + b),
            None => topics.push(TopicInfo {
                name: c.topic.clone(),
                type_name: c.schema.as_ref().map_or(String::new(), |s| s.name.clone()),
                count,
            }),
        }
    }
    Ok(Some(topics))
}

/// Streams the messages of the wanted topics in file order (the data section; the summary is
/// not needed).
pub fn read(path: &Path, wanted: &[Wanted<'_>], visit: &mut Visitor<'_>) -> Result<Flow, String> {
    let mut file = open(path)?;
    // The data section CRC and chunk CRCs are checked when the file has them.
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_validate_chunk_crcs(true)
            .with_skip_end_magic(true),
    );
    let mut schema_names: HashMap<u16, String> = HashMap::new();
    // Channel id → index in `wanted` (None: not wanted).
    let mut channels: HashMap<u16, Option<usize>> = HashMap::new();
    let mut last = (u16::MAX, None);
    while let Some(event) = reader.next_event() {
        let (opcode, data) = match event.map_err(|e| e.to_string())? {
            LinearReadEvent::ReadRequest(n) => {
                let read = file
                    .read(reader.insert(n))
                    .map_err(|e| format!("read failed: {e}"))?;
                reader.notify_read(read);
                continue;
            }
            LinearReadEvent::Record { opcode, data } => (opcode, data),
        };
        match opcode {
            op::MESSAGE => {
                // channel_id u16, sequence u32, log_time u64, publish_time u64, then the data.
                if data.len() < 22 {
                    return Err(format!("a message record of {} bytes", data.len()));
                }
                let channel = u16::from_le_bytes([data[0], data[1]]);
                if channel != last.0 {
                    let Some(&index) = channels.get(&channel) else {
                        return Err(format!("a message on unknown channel {channel}"));
                    };
                    last = (channel, index);
                }
                if let Some(topic) = last.1 {
                    let log_time = u64::from_le_bytes(data[6..14].try_into().expect("8 bytes"));
                    let message = RawMessage {
                        topic,
                        log_time,
                        data: &data[22..],
                    };
                    if visit(message)? == Flow::Stop {
                        return Ok(Flow::Stop);
                    }
                }
            }
            op::SCHEMA | op::CHANNEL => match mcap::parse_record(opcode, data) {
                Ok(Record::Schema { header, .. }) => {
                    schema_names.insert(header.id, header.name);
                }
                Ok(Record::Channel(c)) => {
                    let type_name = schema_names.get(&c.schema_id).map_or("", String::as_str);
                    let index = match_topic(wanted, &c.topic, type_name, &c.message_encoding)?;
                    channels.insert(c.id, index);
                    if last.0 == c.id {
                        last = (c.id, index);
                    }
                }
                Ok(_) => {}
                Err(e) => return Err(e.to_string()),
            },
            op::DATA_END => break,
            _ => {}
        }
    }
    Ok(Flow::Continue)
}

/// Chunk compression of the written file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Compression {
    None,
    Zstd,
    Lz4,
}

/// An MCAP file being written, ROS 2 profile: schemas `ros2msg` (the concatenated message
/// definitions), messages `cdr`, channels carrying `offered_qos_profiles` as rosbag2 does.
pub struct McapWriter {
    inner: mcap::Writer<BufWriter<File>>,
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

impl McapWriter {
    /// Creates (or truncates) `path`. `threads`: zstd worker threads (0: compress in the
    /// calling thread).
    pub fn create(path: &Path, compression: Compression, threads: u32) -> Result<Self, String> {
        let file =
            File::create(path).map_err(|e| format!("cannot create {}: {e}", path.display()))?;
        let options = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!(
                "spatial_dynamics ",
                env!("CARGO_PKG_VERSION"),
                " replay"
            ))
            .compression(match compression {
                Compression::None => None,
                Compression::Zstd => Some(mcap::Compression::Zstd),
                Compression::Lz4 => Some(mcap::Compression::Lz4),
            })
            .compression_threads(threads);
        let inner = options
            .create(BufWriter::with_capacity(1 << 20, file))
            .map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(McapWriter { inner })
    }

    /// Adds a topic; returns its channel id for [`write`](Self::write).
    pub fn add_topic(
        &mut self,
        topic: &str,
        type_name: &str,
        definition: &str,
    ) -> Result<u16, String> {
        let schema = self
            .inner
            .add_schema(type_name, "ros2msg", definition.as_bytes())
            .map_err(|e| e.to_string())?;
        let metadata =
            BTreeMap::from([("offered_qos_profiles".to_string(), OUTPUT_QOS.to_string())]);
        self.inner
            .add_channel(schema, topic, "cdr", &metadata)
            .map_err(|e| e.to_string())
    }

    /// Writes one message (`log_time` also serves as its publish time).
    pub fn write(
        &mut self,
        channel: u16,
        sequence: u32,
        log_time: u64,
        data: &[u8],
    ) -> Result<(), String> {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence,
            log_time,
            publish_time: log_time,
        };
        self.inner
            .write_to_known_channel(&header, data)
            .map_err(|e| e.to_string())
    }

    /// Writes the summary and closes the file.
    pub fn finish(mut self) -> Result<(), String> {
        self.inner.finish().map_err(|e| e.to_string())?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bag::{Bag, Storage};

    /// Files written here with each compression are read back by our reader, messages in order
    /// with their log times, other topics skipped, a wrong type refused.
    #[test]
    fn written_files_read_back_with_every_chunk_compression() {
        let dir = std::env::temp_dir().join(format!("sd_mcap_test_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (compression, name) in [
            (Compression::None, "none"),
            (Compression::Zstd, "zstd"),
            (Compression::Lz4, "lz4"),
        ] {
            let path = dir.join(format!("{name}.mcap"));
            let mut w = McapWriter::create(&path, compression, 0).unwrap();
            let a = w
                .add_topic("/a", "std_msgs/msg/String", "string data\n")
                .unwrap();
            let b = w
                .add_topic("/b", "std_msgs/msg/String", "string data\n")
                .unwrap();
            let mut expected = Vec::new();
            for i in 0..5000u32 {
                let mut data = Vec::new();
                crate::bag::cdr::write_string_msg(&mut data, &format!("message {i}"));
                let channel = if i % 3 == 0 { b } else { a };
                w.write(channel, i, 1_000 + 7 * i as u64, &data).unwrap();
                if channel == a {
                    expected.push((1_000 + 7 * i as u64, format!("message {i}")));
                }
            }
            w.finish().unwrap();

            let bag = Bag::open(&path).unwrap();
            assert_eq!(bag.storage, Storage::Mcap);
            let topics = bag.topics().unwrap().unwrap();
            assert_eq!(topics.len(), 2);
            assert_eq!(topics[0].count, Some(3333));
            let mut got = Vec::new();
            let wanted = [Wanted {
                topic: "/a",
                type_name: "std_msgs/msg/String",
            }];
            bag.read(&wanted, &mut |m| {
                got.push((
                    m.log_time,
                    crate::bag::cdr::parse_string(m.data)?.to_string(),
                ));
                Ok(Flow::Continue)
            })
            .unwrap();
            assert_eq!(got, expected, "{name}");
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
