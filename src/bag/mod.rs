//! rosbag2 bags on disk, read and written without ROS or DDS.
//!
//! A bag is a rosbag2 directory (`metadata.yaml` naming its storage files; without one, the
//! storage files found in it, in split order) or one storage file: MCAP (`.mcap`, chunks
//! uncompressed, zstd or lz4) or sqlite3 (`.db3`). rosbag2's zstd compression is undone on the
//! way: `file` mode (`.mcap.zstd`, `.db3.zstd`) and `message` mode (each message a zstd frame).
//! Messages come out in storage order (MCAP: file order; sqlite3: by log time, then by
//! insertion, as `ros2 bag play` reads them), as CDR bytes borrowed for the duration of one
//! call, so reading allocates nothing per message. Output is an MCAP file with the ROS 2 profile
//! ([`McapWriter`]).
//!
//! Bad input is an error naming the file and the byte offset, record or row, never a panic; an
//! MCAP file cut short (a killed recorder) gives every complete message before the cut, with a
//! warning. Nothing is written beside the bag.
//!
//! Kept apart from the dynamics: this module knows topics, bytes and time stamps only.

pub mod cdr;
mod compression;
mod mcap_reader;
mod mcap_writer;
pub mod msgdefs;
mod sqlite_file;

use compression::TempCopy;
pub use mcap_writer::{ChunkBuilder, Compression, FinishedChunk, McapWriter};
use sqlite_file::Opening;
use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

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
    /// Storage files, in order (as given: `.zstd` ones still compressed).
    pub files: Vec<PathBuf>,
    /// Copies of sqlite3 files, by index in `files`: decompressed (`file`-mode compressed), or
    /// with their write-ahead log ([`sqlite_file`]).
    copies: Vec<Option<Arc<TempCopy>>>,
    /// Topics (with counts) from `metadata.yaml`, if there was one.
    metadata_topics: Vec<TopicInfo>,
}

impl Bag {
    /// Opens a bag directory (with or without `metadata.yaml`) or a single storage file. The
    /// copies it makes of sqlite3 files (decompressed, or with their write-ahead log) stop with
    /// an error, and are removed, once `stop` is set (a signal).
    pub fn open(path: &Path, stop: &AtomicBool) -> Result<Bag, String> {
        let (storage, files, metadata_topics) = if path.is_dir() {
            open_directory(path)?
        } else if !path.is_file() && path.exists() {
            return Err(format!(
                "{} is not a regular file (nor a bag directory)",
                path.display()
            ));
        } else {
            (sniff(path)?, vec![path.to_path_buf()], Vec::new())
        };
        let copies = files
            .iter()
            .map(|file| {
                if storage != Storage::Sqlite3 {
                    return Ok(None);
                }
                if compression::is_zstd_file(file) {
                    return compression::decompress_to_temp(file, stop).map(|c| Some(Arc::new(c)));
                }
                match compression::write_ahead_log(file) {
                    Some(wal) => {
                        warn(&format!(
                            "{}: its write-ahead log {} holds messages not yet in the database \
                             (a recording not closed): reading a copy with the log applied",
                            file.display(),
                            wal.display()
                        ));
                        compression::copy_with_log(file, &wal, stop).map(|c| Some(Arc::new(c)))
                    }
                    None => Ok(None),
                }
            })
            .collect::<Result<_, _>>()?;
        Ok(Bag {
            storage,
            files,
            copies,
            metadata_topics,
        })
    }

    /// The topics of the bag with their types (`pkg/msg/Type`) and counts when known. `None`
    /// when neither the storage files nor `metadata.yaml` list them up front (an MCAP file
    /// without a summary, e.g. from an interrupted recording).
    pub fn topics(&self) -> Result<Option<Vec<TopicInfo>>, String> {
        let mut all: Vec<TopicInfo> = Vec::new();
        let mut listed = true;
        for (k, file) in self.files.iter().enumerate() {
            let topics = match self.storage {
                Storage::Mcap => mcap_reader::topics(file),
                Storage::Sqlite3 => {
                    let (path, opening) = self.local(k);
                    sqlite_file::topics(path, opening).map(Some)
                }
            }
            .map_err(|e| format!("{}: {e}", file.display()))?;
            let Some(topics) = topics else {
                listed = false;
                break;
            };
            for t in topics {
                match all.iter_mut().find(|a| a.name == t.name) {
                    Some(a) => a.count = a.count.zip(t.count).map(|(x, y)| x + y),
                    None => all.push(t),
                }
            }
        }
        if !listed {
            if self.metadata_topics.is_empty() {
                return Ok(None);
            }
            all = self.metadata_topics.clone();
        }
        for t in &mut all {
            if let Some(m) = self.metadata_topics.iter().find(|m| m.name == t.name) {
                t.count = m.count.or(t.count);
            }
            t.type_name = ros2_type_name(&t.type_name).into_owned();
        }
        Ok(Some(all))
    }

    /// Calls `visit` for every message on a `wanted` topic, in storage order, until it returns
    /// [`Flow::Stop`] or an error. A wanted topic recorded with another type, or not as CDR, is
    /// an error naming both types. A file cut short gives its complete messages and a warning on
    /// standard error (see [`Bag::read_noting`]).
    pub fn read(&self, wanted: &[Wanted<'_>], visit: &mut Visitor<'_>) -> Result<(), String> {
        let mut notes = Vec::new();
        let result = self.read_noting(wanted, visit, &mut notes);
        for note in notes {
            warn(&note);
        }
        result
    }

    /// [`Bag::read`], the warnings (a file cut short: which, where, the last log time reached)
    /// pushed to `notes` instead of printed.
    pub fn read_noting(
        &self,
        wanted: &[Wanted<'_>],
        visit: &mut Visitor<'_>,
        notes: &mut Vec<String>,
    ) -> Result<(), String> {
        for (k, file) in self.files.iter().enumerate() {
            let ended = match self.storage {
                Storage::Mcap => mcap_reader::read(file, wanted, visit),
                Storage::Sqlite3 => {
                    let (path, opening) = self.local(k);
                    sqlite_file::read(path, opening, wanted, visit)
                }
            }
            .map_err(|e| format!("{}: {e}", file.display()))?;
            if let Some(note) = ended.note {
                notes.push(format!("{}: {note}", file.display()));
            }
            if ended.flow == Flow::Stop {
                break;
            }
        }
        Ok(())
    }

    /// The file to open for storage file `k`: its copy, if it has one, else the file in place.
    fn local(&self, k: usize) -> (&Path, Opening) {
        match &self.copies[k] {
            Some(copy) => (&copy.path, Opening::Copy),
            None => (&self.files[k], Opening::InPlace),
        }
    }
}

/// Prints a warning the way the command line does.
fn warn(text: &str) {
    eprintln!("spatial_dynamics: warning: {text}");
}

/// A ROS 2 type name as `pkg/msg/Type`: Dashing- and Eloquent-era bags wrote `pkg/Type`.
pub fn ros2_type_name(name: &str) -> Cow<'_, str> {
    match name.split_once('/') {
        Some((pkg, ty)) if !pkg.is_empty() && !ty.is_empty() && !ty.contains('/') => {
            Cow::Owned(format!("{pkg}/msg/{ty}"))
        }
        _ => Cow::Borrowed(name),
    }
}

/// Whether a recorded topic name and a wanted one name the same topic: recorders store
/// `/AAA` or `AAA` (rosbags and some others drop the leading slash) for the same topic.
pub fn same_topic(recorded: &str, wanted: &str) -> bool {
    recorded.trim_start_matches('/') == wanted.trim_start_matches('/')
}

/// Checks a recorded topic against the wanted ones ([`same_topic`]): its index there, or an
/// error for a wrong type or serialization.
fn match_topic(
    wanted: &[Wanted<'_>],
    topic: &str,
    type_name: &str,
    encoding: &str,
) -> Result<Option<usize>, String> {
    let Some(i) = wanted.iter().position(|w| same_topic(topic, w.topic)) else {
        return Ok(None);
    };
    let type_name = ros2_type_name(type_name);
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

/// The storage of a file, from its first bytes (after zstd decompression for `.zstd` files).
fn sniff(path: &Path) -> Result<Storage, String> {
    use std::io::Read;
    let mut magic = Vec::with_capacity(16);
    let result = if compression::is_zstd_file(path) {
        compression::zstd_file_reader(path)?
            .take(16)
            .read_to_end(&mut magic)
    } else {
        std::fs::File::open(path)
            .map_err(|e| format!("cannot open {}: {e}", path.display()))?
            .take(16)
            .read_to_end(&mut magic)
    };
    result.map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    if magic.starts_with(b"\x89MCAP0\r\n") {
        Ok(Storage::Mcap)
    } else if magic.starts_with(b"SQLite format 3\0") {
        Ok(Storage::Sqlite3)
    } else {
        Err(format!(
            "{} is neither an MCAP file nor an sqlite3 database (nor a bag directory)",
            path.display()
        ))
    }
}

/// The storage of a file from its name: `.mcap` / `.db3`, optionally followed by `.zstd`.
fn storage_of_name(path: &Path) -> Option<Storage> {
    let name = path.file_name()?.to_str()?;
    let name = name.strip_suffix(".zstd").unwrap_or(name);
    if name.ends_with(".mcap") {
        Some(Storage::Mcap)
    } else if name.ends_with(".db3") {
        Some(Storage::Sqlite3)
    } else {
        None
    }
}

/// A storage file's bag name and split index (`run.v2_3.db3` → `run.v2`, 3; without an index,
/// the whole name before the storage suffix and 0), for ordering and for telling bags apart.
fn split_parts(path: &Path) -> (String, u64) {
    let name = path
        .file_name()
        .map_or(String::new(), |n| n.to_string_lossy().into_owned());
    let name = name.strip_suffix(".zstd").unwrap_or(&name);
    let stem = [".mcap", ".db3"]
        .iter()
        .find_map(|suffix| name.strip_suffix(suffix))
        .unwrap_or(name);
    match stem.rsplit_once('_') {
        Some((base, n)) if !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()) => {
            (base.to_string(), n.parse().unwrap_or(u64::MAX))
        }
        _ => (stem.to_string(), 0),
    }
}

/// The order of storage files: by split index, then by name.
fn split_index(path: &Path) -> (u64, String) {
    let name = path
        .file_name()
        .map_or(String::new(), |n| n.to_string_lossy().into_owned());
    (split_parts(path).1, name)
}

/// The storage files of a directory, in split order.
fn storage_files(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let entries =
        std::fs::read_dir(dir).map_err(|e| format!("cannot read {}: {e}", dir.display()))?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && storage_of_name(p).is_some())
        .collect();
    files.sort_by_key(|p| split_index(p));
    Ok(files)
}

/// A bag directory: from `metadata.yaml`, or without one (a recording killed before writing
/// it, the case of `ros2 bag reindex`) from its storage files.
fn open_directory(dir: &Path) -> Result<(Storage, Vec<PathBuf>, Vec<TopicInfo>), String> {
    let path = dir.join("metadata.yaml");
    if !path.exists() {
        let files = storage_files(dir)?;
        let Some(first) = files.first() else {
            return Err(format!(
                "{} is not a bag directory: no metadata.yaml and no .mcap or .db3 file",
                dir.display()
            ));
        };
        let storage = storage_of_name(first).expect("a storage file");
        if let Some(other) = files.iter().find(|f| storage_of_name(f) != Some(storage)) {
            return Err(format!(
                "{}: no metadata.yaml, and both {} and {} are in it: which is the bag?",
                dir.display(),
                first.display(),
                other.display()
            ));
        }
        let names: Vec<_> = files.iter().map(|f| split_index(f).1).collect();
        warn(&format!(
            "{}: no metadata.yaml: reading the storage files in it, in split order: {}",
            dir.display(),
            names.join(", ")
        ));
        return Ok((storage, files, Vec::new()));
    }
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
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
    let format = info["compression_format"].as_str().unwrap_or("");
    let compressed = !(mode.is_empty() || mode.eq_ignore_ascii_case("none"));
    if compressed && !format.eq_ignore_ascii_case("zstd") {
        return Err(format!(
            "{}: compression format '{format}' ({mode} mode) is not supported: rosbag2 writes zstd",
            path.display()
        ));
    }
    if compressed && !(mode.eq_ignore_ascii_case("file") || mode.eq_ignore_ascii_case("message")) {
        return Err(format!(
            "{}: compression mode '{mode}' is not supported (file, message)",
            path.display()
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
            // In `file` mode the listed name may or may not carry the `.zstd`.
            let zstd = PathBuf::from(format!("{}.zstd", file.display()));
            if file.is_file() {
                Ok(file)
            } else if zstd.is_file() {
                Ok(zstd)
            } else {
                Err(format!(
                    "{}: file {} is missing",
                    path.display(),
                    file.display()
                ))
            }
        })
        .collect::<Result<Vec<_>, String>>()?;
    // A file listed twice would be read twice.
    let listed = files.len();
    let mut unique: Vec<PathBuf> = Vec::with_capacity(listed);
    for file in files {
        let same = |f: &PathBuf| {
            f == &file
                || std::fs::canonicalize(f)
                    .ok()
                    .is_some_and(|c| std::fs::canonicalize(&file).is_ok_and(|d| c == d))
        };
        if !unique.iter().any(same) {
            unique.push(file);
        }
    }
    if unique.len() < listed {
        warn(&format!(
            "{}: lists {listed} storage files, of which {} are distinct: each is read once",
            path.display(),
            unique.len()
        ));
    }
    let mut files = unique;
    // A metadata.yaml left from before a split (a killed recorder): the later files of the
    // same bag (same name, higher split index) are read too.
    let base = |p: &Path| split_parts(p).0;
    let bases: Vec<String> = files.iter().map(|f| base(f)).collect();
    let last = files.iter().map(|f| split_index(f).0).max().unwrap_or(0);
    let extra: Vec<PathBuf> = storage_files(dir)?
        .into_iter()
        .filter(|f| {
            storage_of_name(f) == Some(storage)
                && bases.contains(&base(f))
                && split_index(f).0 > last
                && !files.contains(f)
        })
        .collect();
    if !extra.is_empty() {
        let names: Vec<_> = extra.iter().map(|f| split_index(f).1).collect();
        warn(&format!(
            "{}: out of date: also reading {}, not listed in it",
            path.display(),
            names.join(", ")
        ));
        files.extend(extra);
    }
    let mut metadata_topics = Vec::new();
    if let Some(topics) = info["topics_with_message_count"].as_sequence() {
        for t in topics {
            if let (Some(name), Some(type_name)) = (
                t["topic_metadata"]["name"].as_str(),
                t["topic_metadata"]["type"].as_str(),
            ) {
                metadata_topics.push(TopicInfo {
                    name: name.to_string(),
                    type_name: type_name.to_string(),
                    count: t["message_count"].as_u64(),
                });
            }
        }
    }
    Ok((storage, files, metadata_topics))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn old_type_names_gain_their_msg() {
        assert_eq!(
            ros2_type_name("sensor_msgs/JointState"),
            "sensor_msgs/msg/JointState"
        );
        assert_eq!(
            ros2_type_name("sensor_msgs/msg/JointState"),
            "sensor_msgs/msg/JointState"
        );
        assert_eq!(ros2_type_name("JointState"), "JointState");
        assert_eq!(ros2_type_name("/x"), "/x");
        let wanted = [Wanted {
            topic: "/j",
            type_name: "sensor_msgs/msg/JointState",
        }];
        assert_eq!(
            match_topic(&wanted, "/j", "sensor_msgs/JointState", "cdr"),
            Ok(Some(0))
        );
        assert!(match_topic(&wanted, "/j", "std_msgs/String", "cdr").is_err());
    }

    /// A database whose latest messages are still in its write-ahead log (a recorder killed in
    /// WAL mode) gives every message, read from a copy: nothing is created beside the bag.
    #[test]
    fn messages_in_a_write_ahead_log_are_read() {
        let dir = std::env::temp_dir().join(format!("sd_wal_{}", std::process::id()));
        let bag = dir.join("bag");
        std::fs::create_dir_all(&bag).unwrap();
        let live = dir.join("live.db3");
        let db = rusqlite::Connection::open(&live).unwrap();
        db.execute_batch(&format!(
            "PRAGMA journal_mode=WAL; PRAGMA wal_autocheckpoint=0; {}
             INSERT INTO topics VALUES (1, '/s', 'std_msgs/msg/String', 'cdr', '');
             INSERT INTO messages VALUES (1, 1, 10, X'000100000300000061620000');
             PRAGMA wal_checkpoint(TRUNCATE);
             INSERT INTO messages VALUES (2, 1, 20, X'000100000300000068690000');",
            sqlite_file::ROSBAG2_TABLES
        ))
        .unwrap();
        // What a killed recorder leaves: the database and its log, the second row only in the log.
        std::fs::copy(&live, bag.join("bag_0.db3")).unwrap();
        std::fs::copy(dir.join("live.db3-wal"), bag.join("bag_0.db3-wal")).unwrap();
        drop(db);
        let listing = || {
            let mut names: Vec<_> = std::fs::read_dir(&bag)
                .unwrap()
                .map(|e| e.unwrap().file_name())
                .collect();
            names.sort();
            names
        };
        let before = listing();
        let opened = Bag::open(&bag, &Default::default()).unwrap();
        let wanted = [Wanted {
            topic: "/s",
            type_name: "std_msgs/msg/String",
        }];
        let mut times = Vec::new();
        opened
            .read(&wanted, &mut |m| {
                times.push(m.log_time);
                Ok(Flow::Continue)
            })
            .unwrap();
        assert_eq!(times, [10, 20]);
        let copy = opened.copies[0].as_ref().unwrap().path.clone();
        drop(opened);
        assert!(!copy.exists(), "the copy is removed with the bag");
        assert_eq!(listing(), before, "nothing created beside the bag");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bag_names_with_dots_keep_their_split_index() {
        assert_eq!(
            split_parts(Path::new("run.v2_11.mcap")),
            ("run.v2".to_string(), 11)
        );
        assert_eq!(
            split_parts(Path::new("d/run.v2_3.db3.zstd")),
            ("run.v2".to_string(), 3)
        );
        assert_eq!(
            split_parts(Path::new("plain.mcap")),
            ("plain".to_string(), 0)
        );
        assert_eq!(split_parts(Path::new("a_b.mcap")), ("a_b".to_string(), 0));
        let mut files: Vec<PathBuf> = ["r.v2_10.mcap", "r.v2_2.mcap", "r.v2_0.mcap"]
            .iter()
            .map(PathBuf::from)
            .collect();
        files.sort_by_key(|p| split_index(p));
        assert_eq!(files[2], Path::new("r.v2_10.mcap"));
    }

    #[test]
    fn split_files_are_ordered_by_their_index() {
        let mut files: Vec<PathBuf> = ["b_10.db3", "b_2.db3", "b_0.db3.zstd", "b_1.db3"]
            .iter()
            .map(PathBuf::from)
            .collect();
        files.sort_by_key(|p| split_index(p));
        let names: Vec<_> = files.iter().map(|p| p.to_str().unwrap()).collect();
        assert_eq!(names, ["b_0.db3.zstd", "b_1.db3", "b_2.db3", "b_10.db3"]);
        assert_eq!(
            storage_of_name(Path::new("x.mcap.zstd")),
            Some(Storage::Mcap)
        );
        assert_eq!(storage_of_name(Path::new("x.yaml")), None);
    }
}
