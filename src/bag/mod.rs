//! rosbag2 bags on disk, read and written without ROS or DDS.
//!
//! A bag is a rosbag2 directory (`metadata.yaml` naming its storage files) or one storage file:
//! MCAP (`.mcap`, chunks uncompressed, zstd or lz4) or sqlite3 (`.db3`). Messages come out in
//! storage order (MCAP: file order; sqlite3: by log time, then by insertion, as `ros2 bag play`
//! reads them), as CDR bytes borrowed for the duration of one call, so reading allocates nothing
//! per message. Output is an MCAP file with the ROS 2 profile ([`McapWriter`]).
//!
//! Kept apart from the dynamics: this module knows topics, bytes and time stamps only.

pub mod cdr;
mod mcap_file;
pub mod msgdefs;
mod sqlite_file;

pub use mcap_file::{ChunkBuilder, Compression, FinishedChunk, McapWriter};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The storage format of a bag.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Storage {
    Mcap,
    Sqlite3,
}

/// A topic recorded in a bag.
#[derive(Clone, Debug, PartialEq)]
pub struct TopicInfo {
    /// Fully qualified name, e.g. `/joint_states`.
    pub name: String,
    /// ROS 2 type, e.g. `sensor_msgs/msg/JointState`.
    pub type_name: String,
    /// Number of messages, when the bag says so (MCAP summary, `metadata.yaml`).
    pub count: Option<u64>,
}

/// A topic to read, and the type its messages must have.
#[derive(Clone, Copy, Debug)]
pub struct Wanted<'a> {
    pub topic: &'a str,
    pub type_name: &'a str,
}

/// One message handed to the visitor of [`Bag::read`].
#[derive(Clone, Copy, Debug)]
pub struct RawMessage<'a> {
    /// Index of its topic in the `wanted` list.
    pub topic: usize,
    /// Log (receive) time, ns since the epoch.
    pub log_time: u64,
    /// Serialized message (CDR with its encapsulation header).
    pub data: &'a [u8],
}

/// Whether [`Bag::read`] goes on after a message.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Flow {
    Continue,
    Stop,
}

/// The visitor of [`Bag::read`].
pub type Visitor<'v> = dyn FnMut(RawMessage<'_>) -> Result<Flow, String> + 'v;

/// A bag opened for reading.
#[derive(Clone, Debug)]
pub struct Bag {
    pub storage: Storage,
    /// Storage files, in order.
    pub files: Vec<PathBuf>,
    /// Message counts by topic from `metadata.yaml`, if there was one.
    metadata_counts: HashMap<String, u64>,
}

impl Bag {
    /// Opens a bag directory (with `metadata.yaml`) or a single `.mcap` or `.db3` file.
    pub fn open(path: &Path) -> Result<Bag, String> {
        if path.is_dir() {
            return open_directory(path);
        }
        let storage = sniff(path)?;
        Ok(Bag {
            storage,
            files: vec![path.to_path_buf()],
            metadata_counts: HashMap::new(),
        })
    }

    /// The topics of the bag with their types (and counts when known). `None` when the bag does
    /// not list them up front (an MCAP file without a summary, e.g. from an interrupted recording).
    pub fn topics(&self) -> Result<Option<Vec<TopicInfo>>, String> {
        let mut all: Vec<TopicInfo> = Vec::new();
        for file in &self.files {
            let topics = match self.storage {
                Storage::Mcap => match mcap_file::topics(file)? {
                    Some(t) => t,
                    None => return Ok(None),
                },
                Storage::Sqlite3 => sqlite_file::topics(file)?,
            };
            for t in topics {
                match all.iter_mut().find(|a| a.name == t.name) {
                    Some(a) => {
                        a.count = match (a.count, t.count) {
                            (Some(x), Some(y)) => Some(x + y),
                            _ => None,
                        }
                    }
                    None => all.push(t),
                }
            }
        }
        for t in &mut all {
            if let Some(&n) = self.metadata_counts.get(&t.name) {
                t.count = Some(n);
            }
        }
        Ok(Some(all))
    }

    /// Calls `visit` for every message on a `wanted` topic, in storage order, until it returns
    /// [`Flow::Stop`] or an error. A wanted topic recorded with another type, or not as CDR, is
    /// an error naming both types.
    pub fn read(&self, wanted: &[Wanted<'_>], visit: &mut Visitor<'_>) -> Result<(), String> {
        for file in &self.files {
            let flow = match self.storage {
                Storage::Mcap => mcap_file::read(file, wanted, visit),
                Storage::Sqlite3 => sqlite_file::read(file, wanted, visit),
            }
            .map_err(|e| format!("{}: {e}", file.display()))?;
            if flow == Flow::Stop {
                break;
            }
        }
        Ok(())
    }
}

/// Checks a recorded topic against the wanted ones: its index there, or an error for a wrong
/// type or serialization.
fn match_topic(
    wanted: &[Wanted<'_>],
    topic: &str,
    type_name: &str,
    encoding: &str,
) -> Result<Option<usize>, String> {
    let Some(i) = wanted.iter().position(|w| w.topic == topic) else {
        return Ok(None);
    };
    if type_name != wanted[i].type_name {
        return Err(format!(
            "topic {topic} has type {type_name}, expected {}",
            wanted[i].type_name
        ));
    }
    if encoding != "cdr" {
        return Err(format!(
            "topic {topic} is serialized as '{encoding}', expected 'cdr'"
        ));
    }
    Ok(Some(i))
}

fn sniff(path: &Path) -> Result<Storage, String> {
    use std::io::Read;
    let mut magic = [0u8; 16];
    let mut file =
        std::fs::File::open(path).map_err(|e| format!("cannot open {}: {e}", path.display()))?;
    let n = file
        .read(&mut magic)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    if magic[..n].starts_with(b"\x89MCAP0\r\n") {
        Ok(Storage::Mcap)
    } else if magic[..n].starts_with(b"SQLite format 3\0") {
        Ok(Storage::Sqlite3)
    } else {
        Err(format!(
            "{} is neither an MCAP file nor an sqlite3 database (nor a bag directory with metadata.yaml)",
            path.display()
        ))
    }
}

fn open_directory(dir: &Path) -> Result<Bag, String> {
    let path = dir.join("metadata.yaml");
    let text = std::fs::read_to_string(&path).map_err(|e| {
        format!(
            "{} is not a bag directory: {}: {e}",
            dir.display(),
            path.display()
        )
    })?;
    let yaml: serde_norway::Value =
        serde_norway::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let info = &yaml["rosbag2_bagfile_information"];
    let field = |name: &str| {
        info[name]
            .as_str()
            .map(str::to_string)
            .ok_or_else(|| format!("{}: no {name}", path.display()))
    };
    let storage = match field("storage_identifier")?.as_str() {
        "mcap" => Storage::Mcap,
        "sqlite3" => Storage::Sqlite3,
        other => {
            return Err(format!(
                "{}: storage '{other}' is not supported (mcap, sqlite3)",
                path.display()
            ))
        }
    };
    let mode = info["compression_mode"].as_str().unwrap_or("");
    if !(mode.is_empty() || mode.eq_ignore_ascii_case("none")) {
        return Err(format!(
            "{}: compression_mode {mode} ({}) is not supported: decompress the bag first \
             (MCAP chunk compression, zstd or lz4, needs no such step)",
            path.display(),
            info["compression_format"].as_str().unwrap_or("?")
        ));
    }
    let files = info["relative_file_paths"]
        .as_sequence()
        .ok_or_else(|| format!("{}: no relative_file_paths", path.display()))?
        .iter()
        .map(|f| {
            let name = f
                .as_str()
                .ok_or_else(|| format!("{}: a file path is not a string", path.display()))?;
            // Older rosbag2 versions wrote the paths with the bag directory in front.
            let file = Path::new(name)
                .file_name()
                .map(|n| dir.join(n))
                .ok_or_else(|| format!("{}: bad file path '{name}'", path.display()))?;
            if file.is_file() {
                Ok(file)
            } else {
                Err(format!(
                    "{}: file {} is missing",
                    path.display(),
                    file.display()
                ))
            }
        })
        .collect::<Result<Vec<_>, String>>()?;
    let mut metadata_counts = HashMap::new();
    if let Some(topics) = info["topics_with_message_count"].as_sequence() {
        for t in topics {
            if let (Some(name), Some(n)) = (
                t["topic_metadata"]["name"].as_str(),
                t["message_count"].as_u64(),
            ) {
                metadata_counts.insert(name.to_string(), n);
            }
        }
    }
    Ok(Bag {
        storage,
        files,
        metadata_counts,
    })
}
