//! rosbag2's sqlite3 storage: tables `topics(id, name, type, serialization_format, …)` and
//! `messages(id, topic_id, timestamp, data)`; read-only, messages ordered by `timestamp` then
//! `id` (insertion), which is how `ros2 bag play` orders them.

use super::{match_topic, Flow, RawMessage, TopicInfo, Visitor, Wanted};
use rusqlite::{Connection, OpenFlags};
use std::path::Path;

fn open(path: &Path) -> Result<Connection, String> {
    Connection::open_with_flags(
        path,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(|e| format!("cannot open {}: {e}", path.display()))
}

fn topic_rows(db: &Connection) -> Result<Vec<(i64, String, String, String)>, String> {
    let mut stmt = db
        .prepare("SELECT id, name, type, serialization_format FROM topics")
        .map_err(|e| format!("not a rosbag2 database: {e}"))?;
    let rows = stmt
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)))
        .map_err(|e| e.to_string())?;
    rows.collect::<Result<_, _>>().map_err(|e| e.to_string())
}

/// The topics table (counts are not in the database; `metadata.yaml` has them).
pub fn topics(path: &Path) -> Result<Vec<TopicInfo>, String> {
    let db = open(path)?;
    Ok(topic_rows(&db)
        .map_err(|e| format!("{}: {e}", path.display()))?
        .into_iter()
        .map(|(_, name, type_name, _)| TopicInfo {
            name,
            type_name,
            count: None,
        })
        .collect())
}

/// Streams the messages of the wanted topics by log time.
pub fn read(path: &Path, wanted: &[Wanted<'_>], visit: &mut Visitor<'_>) -> Result<Flow, String> {
    let db = open(path)?;
    let mut ids: Vec<(i64, usize)> = Vec::new();
    for (id, name, type_name, encoding) in topic_rows(&db)? {
        if let Some(index) = match_topic(wanted, &name, &type_name, &encoding)? {
            ids.push((id, index));
        }
    }
    if ids.is_empty() {
        return Ok(Flow::Continue);
    }
    let list = ids
        .iter()
        .map(|(id, _)| id.to_string())
        .collect::<Vec<_>>()
        .join(",");
    // The (timestamp, rowid) index rosbag2 creates serves this order without a sort.
    let mut stmt = db
        .prepare(&format!(
            "SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN ({list}) \
             ORDER BY timestamp, id"
        ))
        .map_err(|e| e.to_string())?;
    let mut rows = stmt.query([]).map_err(|e| e.to_string())?;
    while let Some(row) = rows.next().map_err(|e| e.to_string())? {
        let topic_id: i64 = row.get(0).map_err(|e| e.to_string())?;
        let timestamp: i64 = row.get(1).map_err(|e| e.to_string())?;
        let data = row
            .get_ref(2)
            .and_then(|v| v.as_blob().map_err(Into::into))
            .map_err(|e| format!("message data: {e}"))?;
        let topic = ids
            .iter()
            .find(|(id, _)| *id == topic_id)
            .map(|(_, i)| *i)
            .expect("selected topics only");
        let message = RawMessage {
            topic,
            log_time: timestamp.max(0) as u64,
            data,
        };
        if visit(message)? == Flow::Stop {
            return Ok(Flow::Stop);
        }
    }
    Ok(Flow::Continue)
}
