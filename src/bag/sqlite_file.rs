//! rosbag2's sqlite3 storage: tables `topics(id, name, type, serialization_format, …)` and
//! `messages(id, topic_id, timestamp, data)`; messages ordered by `timestamp` then `id`
//! (insertion), which is how `ros2 bag play` orders them. Everything comes from the database
//! itself, so a bag whose `metadata.yaml` is missing or out of date reads the same.
//!
//! A bag's own file is opened read-only and immutable (an SQLite URI with `mode=ro&immutable=1`):
//! SQLite then creates no `-wal`, `-shm` or journal file beside the bag, and takes no lock. An
//! immutable database ignores its write-ahead log, so a database with a non-empty `-wal` beside
//! it (a recorder killed in WAL mode) is read from a copy of both in the temporary directory,
//! which SQLite opens normally and applies the log to ([`Opening::Copy`]). Text that is not
//! UTF-8 and values of the wrong kind are errors naming the table, column and row; a message
//! with a negative log time is skipped and counted in the note [`read`] returns.

use super::compression;
use super::mcap_reader::Ended;
use super::{match_topic, Flow, RawMessage, TopicInfo, Visitor, Wanted};
use rusqlite::types::ValueRef;
use rusqlite::{Connection, OpenFlags, Row};
use std::path::Path;

/// How a database file is opened.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Opening {
    /// The bag's own file: read-only and immutable, nothing written beside it.
    InPlace,
    /// A copy of ours in the temporary directory: opened normally, so that SQLite applies a
    /// write-ahead log beside it.
    Copy,
}

/// `path` as an immutable SQLite URI: `file:` and the path, `%`, `?` and `#` percent-encoded.
fn uri(path: &Path) -> Result<String, String> {
    let absolute = std::path::absolute(path).map_err(|e| format!("cannot open: {e}"))?;
    let text = absolute
        .to_str()
        .ok_or_else(|| "cannot open: the path is not UTF-8".to_string())?;
    let mut out = String::from("file:");
    for c in text.chars() {
        match c {
            '%' => out.push_str("%25"),
            '?' => out.push_str("%3f"),
            '#' => out.push_str("%23"),
            c => out.push(c),
        }
    }
    out.push_str("?mode=ro&immutable=1");
    Ok(out)
}

fn open(path: &Path, opening: Opening) -> Result<Connection, String> {
    match opening {
        Opening::InPlace => Connection::open_with_flags(
            uri(path)?,
            OpenFlags::SQLITE_OPEN_READ_ONLY
                | OpenFlags::SQLITE_OPEN_URI
                | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        ),
        Opening::Copy => Connection::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_WRITE | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        ),
    }
    .map_err(|e| format!("cannot open: {e}"))
}

/// Where a value is: the table, the column and the row's id (column 0), for errors.
fn place(row: &Row<'_>, table: &str, column: &str) -> String {
    let id = row.get_ref(0).ok().and_then(|v| v.as_i64().ok());
    format!(
        "table {table}, column {column}, row with id {}",
        id.map_or("?".into(), |i| i.to_string())
    )
}

/// Column `k` (named `column`) of a row of `table` as text.
fn text<'r>(row: &'r Row<'_>, k: usize, table: &str, column: &str) -> Result<&'r str, String> {
    let at = || place(row, table, column);
    match row.get_ref(k).map_err(|e| format!("{}: {e}", at()))? {
        ValueRef::Text(bytes) => {
            std::str::from_utf8(bytes).map_err(|e| format!("{}: not UTF-8 ({e})", at()))
        }
        other => Err(format!(
            "{}: {:?} where text belongs",
            at(),
            other.data_type()
        )),
    }
}

/// Column `k` (named `column`) of a row of `table` as an integer.
fn integer(row: &Row<'_>, k: usize, table: &str, column: &str) -> Result<i64, String> {
    match row.get_ref(k) {
        Ok(ValueRef::Integer(i)) => Ok(i),
        Ok(other) => Err(format!(
            "{}: {:?} where an integer belongs",
            place(row, table, column),
            other.data_type()
        )),
        Err(e) => Err(format!("{}: {e}", place(row, table, column))),
    }
}

/// `(id, name, type, serialization_format)` of every topic.
fn topic_rows(db: &Connection) -> Result<Vec<(i64, String, String, String)>, String> {
    let mut stmt = db
        .prepare("SELECT id, name, type, serialization_format FROM topics")
        .map_err(|e| format!("not a rosbag2 database: {e}"))?;
    let mut rows = stmt.query([]).map_err(|e| e.to_string())?;
    let mut out = Vec::new();
    while let Some(row) = rows.next().map_err(|e| format!("table topics: {e}"))? {
        out.push((
            integer(row, 0, "topics", "id")?,
            text(row, 1, "topics", "name")?.to_string(),
            text(row, 2, "topics", "type")?.to_string(),
            text(row, 3, "topics", "serialization_format")?.to_string(),
        ));
    }
    Ok(out)
}

/// The topics table (counts are not in the database; `metadata.yaml` has them).
pub fn topics(path: &Path, opening: Opening) -> Result<Vec<TopicInfo>, String> {
    let db = open(path, opening)?;
    Ok(topic_rows(&db)?
        .into_iter()
        .map(|(_, name, type_name, _)| TopicInfo {
            name,
            type_name,
            count: None,
        })
        .collect())
}

/// Streams the messages of the wanted topics by log time. A message stored zstd-compressed
/// (rosbag2's `message` compression mode) is decompressed first. A message with a negative log
/// time is skipped; the note says how many and the first.
pub fn read(
    path: &Path,
    opening: Opening,
    wanted: &[Wanted<'_>],
    visit: &mut Visitor<'_>,
) -> Result<Ended, String> {
    let db = open(path, opening)?;
    let mut ids: Vec<(i64, usize)> = Vec::new();
    for (id, name, type_name, encoding) in topic_rows(&db)? {
        if let Some(index) = match_topic(wanted, &name, &type_name, &encoding)? {
            ids.push((id, index));
        }
    }
    let continued = Ended {
        flow: Flow::Continue,
        note: None,
    };
    if ids.is_empty() {
        return Ok(continued);
    }
    let list = ids
        .iter()
        .map(|(id, _)| id.to_string())
        .collect::<Vec<_>>()
        .join(",");
    // The (timestamp, rowid) index rosbag2 creates serves this order without a sort.
    let mut stmt = db
        .prepare(&format!(
            "SELECT id, topic_id, timestamp, data FROM messages WHERE topic_id IN ({list}) \
             ORDER BY timestamp, id"
        ))
        .map_err(|e| format!("not a rosbag2 database: {e}"))?;
    let mut rows = stmt.query([]).map_err(|e| e.to_string())?;
    let mut zstd = None;
    let mut plain = Vec::new();
    let mut last_id = None;
    // Negative log times: how many, and the first (row id, timestamp).
    let mut negative: (u64, Option<(i64, i64)>) = (0, None);
    let skipped_note = |(count, first): (u64, Option<(i64, i64)>)| {
        first.map(|(id, t)| {
            format!(
                "skipped {count} messages with a negative log time (the first: table messages, \
                 row with id {id}, timestamp {t})"
            )
        })
    };
    while let Some(row) = rows.next().map_err(|e| match last_id {
        Some(id) => format!("table messages, after the row with id {id}: {e}"),
        None => format!("table messages: {e}"),
    })? {
        let id = integer(row, 0, "messages", "id")?;
        last_id = Some(id);
        let at = |column: &str| format!("table messages, column {column}, row with id {id}");
        let topic_id = integer(row, 1, "messages", "topic_id")?;
        let timestamp = integer(row, 2, "messages", "timestamp")?;
        let Ok(log_time) = u64::try_from(timestamp) else {
            negative.0 += 1;
            negative.1.get_or_insert((id, timestamp));
            continue;
        };
        let mut data = match row.get_ref(3) {
            Ok(ValueRef::Blob(b)) => b,
            _ => return Err(format!("{}: not a blob", at("data"))),
        };
        if compression::is_zstd(data) {
            compression::zstd_into(&mut zstd, data, None, &mut plain)
                .map_err(|e| format!("{}: {e}", at("data")))?;
            data = &plain;
        }
        let Some(&(_, topic)) = ids.iter().find(|(t, _)| *t == topic_id) else {
            return Err(format!(
                "{}: topic {topic_id} was not selected",
                at("topic_id")
            ));
        };
        let message = RawMessage {
            topic,
            log_time,
            data,
        };
        if visit(message)? == Flow::Stop {
            return Ok(Ended {
                flow: Flow::Stop,
                note: skipped_note(negative),
            });
        }
    }
    Ok(Ended {
        flow: Flow::Continue,
        note: skipped_note(negative),
    })
}

/// The two tables of a rosbag2 database, as its recorder creates them (tests make bags with
/// them).
#[cfg(test)]
pub(crate) const ROSBAG2_TABLES: &str =
    "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
         serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
     CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
         timestamp INTEGER NOT NULL, data BLOB NOT NULL);";

#[cfg(test)]
mod tests {
    use super::*;

    /// A rosbag2-shaped database in WAL mode (as a live recorder leaves it), with a Dashing-era
    /// type name, and a topic whose name is not UTF-8.
    #[test]
    fn databases_are_read_in_place_and_bad_text_is_named() {
        let dir = std::env::temp_dir().join(format!("sd_sqlite_test_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bag_0.db3");
        {
            let db = Connection::open(&path).unwrap();
            db.execute_batch(&format!(
                "PRAGMA journal_mode=WAL; {ROSBAG2_TABLES}
                 INSERT INTO topics VALUES (1, '/s', 'std_msgs/String', 'cdr', '');
                 INSERT INTO messages VALUES (1, 1, 20, X'000100000300000068690000');
                 INSERT INTO messages VALUES (2, 1, 10, X'000100000300000061620000');
                 PRAGMA wal_checkpoint(TRUNCATE);"
            ))
            .unwrap();
        }
        for extra in ["-wal", "-shm"] {
            let _ = std::fs::remove_file(dir.join(format!("bag_0.db3{extra}")));
        }
        let listing = || {
            let mut names: Vec<_> = std::fs::read_dir(&dir)
                .unwrap()
                .map(|e| e.unwrap().file_name())
                .collect();
            names.sort();
            names
        };
        let before = listing();
        let wanted = [Wanted {
            topic: "/s",
            type_name: "std_msgs/msg/String",
        }];
        let mut got = Vec::new();
        read(&path, Opening::InPlace, &wanted, &mut |m| {
            got.push((
                m.log_time,
                crate::bag::cdr::parse_string(m.data)?.to_string(),
            ));
            Ok(Flow::Continue)
        })
        .unwrap();
        assert_eq!(got, [(10, "ab".to_string()), (20, "hi".to_string())]);
        assert_eq!(listing(), before, "nothing created beside the database");

        let db = Connection::open(&path).unwrap();
        db.execute_batch(
            "PRAGMA journal_mode=DELETE;
             INSERT INTO topics VALUES (7, CAST(X'2fff41' AS TEXT), 'std_msgs/msg/String', 'cdr', '');",
        )
        .unwrap();
        drop(db);
        let err = topics(&path, Opening::InPlace).unwrap_err();
        assert!(
            err.contains("table topics, column name, row with id 7") && err.contains("UTF-8"),
            "{err}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A negative log time is skipped and counted; a value of the wrong kind names its row and
    /// what it holds.
    #[test]
    fn negative_log_times_are_skipped_and_counted() {
        let dir = std::env::temp_dir().join(format!("sd_sqlite_neg_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("neg_0.db3");
        let db = Connection::open(&path).unwrap();
        db.execute_batch(
            "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
                 serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
             CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
                 timestamp, data BLOB NOT NULL);
             INSERT INTO topics VALUES (1, '/s', 'std_msgs/msg/String', 'cdr', '');
             INSERT INTO messages VALUES (1, 1, -5, X'000100000300000068690000');
             INSERT INTO messages VALUES (2, 1, -1, X'000100000300000068690000');
             INSERT INTO messages VALUES (3, 1, 10, X'000100000300000061620000');",
        )
        .unwrap();
        let wanted = [Wanted {
            topic: "/s",
            type_name: "std_msgs/msg/String",
        }];
        let mut times = Vec::new();
        let ended = read(&path, Opening::InPlace, &wanted, &mut |m| {
            times.push(m.log_time);
            Ok(Flow::Continue)
        })
        .unwrap();
        assert_eq!(times, [10]);
        let note = ended.note.unwrap();
        assert!(
            note.contains("skipped 2 messages with a negative log time")
                && note.contains("row with id 1, timestamp -5"),
            "{note}"
        );
        db.execute_batch("UPDATE messages SET timestamp = 2.5 WHERE id = 3;")
            .unwrap();
        let err = read(&path, Opening::InPlace, &wanted, &mut |_| {
            Ok(Flow::Continue)
        })
        .unwrap_err();
        assert!(
            err.contains("column timestamp, row with id 3: Real where an integer belongs"),
            "{err}"
        );
        drop(db);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
