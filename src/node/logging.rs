//! The node's log. Every line goes to stderr in rclcpp's console format
//! (`[LEVEL] [SECONDS.NANOS] [LOGGER]: message`) and, once the node exists, to `/rosout` as
//! `rcl_interfaces/msg/Log`, as an rclcpp node logs:
//!
//! - the logger name is rcl's: the node's namespace and name joined by dots, without the leading
//!   slash (`spatial_dynamics`, `robot1.spatial_dynamics`);
//! - levels are rcutils' severities (DEBUG 10, INFO 20, WARN 30, ERROR 40, FATAL 50); a line below
//!   the logger's level goes nowhere. The level comes from `--log-level LEVEL` (default INFO) or
//!   `--log-level NAME:=LEVEL`, where NAME is this logger or one of its ancestors (`robot1`): the
//!   most specific name wins, as rcutils resolves logger levels;
//! - `/rosout` has rcl's rosout QoS (`rmw_qos_profile_rosout_default`): reliable, transient local,
//!   keep last 1000, lifespan 10 s, so a subscriber that joins late still gets the recent lines;
//! - lines logged before the node exists (start-up) are kept, up to that depth, and published
//!   when the `/rosout` publisher is attached;
//! - stamps are the system (wall) clock, as rcutils stamps its log records.

use crate::ros::msgs::{Log, Time};
use ros2_client::Publisher;
use std::sync::{Arc, Mutex};
use std::time::SystemTime;

/// Lines kept for `/rosout` before the node exists: the depth of the rosout topic.
pub const ROSOUT_DEPTH: usize = 1000;

/// rcutils' log severities.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    Debug = 10,
    Info = 20,
    Warn = 30,
    Error = 40,
    Fatal = 50,
}

impl Level {
    /// A severity as `--log-level` takes it: `debug`, `info`, `warn`, `error`, `fatal`, any case.
    pub fn parse(text: &str) -> Result<Level, String> {
        match text.to_ascii_lowercase().as_str() {
            "debug" => Ok(Level::Debug),
            "info" => Ok(Level::Info),
            "warn" | "warning" => Ok(Level::Warn),
            "error" => Ok(Level::Error),
            "fatal" => Ok(Level::Fatal),
            _ => Err(format!(
                "--log-level: unknown severity '{text}' (debug, info, warn, error, fatal)"
            )),
        }
    }

    fn name(self) -> &'static str {
        match self {
            Level::Debug => "DEBUG",
            Level::Info => "INFO",
            Level::Warn => "WARN",
            Level::Error => "ERROR",
            Level::Fatal => "FATAL",
        }
    }
}

/// rcl's logger name of node `node` in namespace `namespace` (absolute, `/` for none).
pub fn logger_name(namespace: &str, node: &str) -> String {
    namespace
        .split('/')
        .filter(|part| !part.is_empty())
        .chain([node])
        .collect::<Vec<_>>()
        .join(".")
}

/// The level of logger `name` from `--log-level` settings (`None`: the default for all loggers;
/// `Some(NAME)`: that logger and its descendants), later settings overriding earlier ones.
pub fn level_for(name: &str, settings: &[(Option<String>, Level)]) -> Level {
    let mut default = Level::Info;
    let mut specific: Option<(usize, Level)> = None;
    for (logger, level) in settings {
        match logger {
            None => default = *level,
            Some(l) if name == l || name.starts_with(&format!("{l}.")) => {
                if specific.is_none_or(|(len, _)| l.len() >= len) {
                    specific = Some((l.len(), *level));
                }
            }
            Some(_) => {}
        }
    }
    specific.map_or(default, |(_, level)| level)
}

/// The node's logger: cheap to clone, every clone writes to the same outputs.
#[derive(Clone)]
pub struct Logger {
    inner: Arc<Mutex<Inner>>,
    name: Arc<str>,
    threshold: Level,
}

impl std::fmt::Debug for Logger {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Logger({}, {:?})", self.name, self.threshold)
    }
}

struct Inner {
    rosout: Option<Publisher<Log>>,
    /// Lines waiting for the `/rosout` publisher (at most [`ROSOUT_DEPTH`]).
    backlog: Vec<Log>,
}

impl Logger {
    /// A logger called `name` that writes lines at `threshold` or above.
    pub fn new(name: &str, threshold: Level) -> Logger {
        Logger {
            inner: Arc::new(Mutex::new(Inner {
                rosout: None,
                backlog: Vec::new(),
            })),
            name: name.into(),
            threshold,
        }
    }

    /// Whether a line at `level` is written.
    pub fn enabled(&self, level: Level) -> bool {
        level >= self.threshold
    }

    /// From now on, lines also go to `/rosout` through `publisher`; the lines logged so far
    /// are published first.
    pub fn attach(&self, publisher: Publisher<Log>) {
        let Ok(mut inner) = self.inner.lock() else {
            return;
        };
        for line in std::mem::take(&mut inner.backlog) {
            let _ = publisher.publish(line);
        }
        inner.rosout = Some(publisher);
    }

    /// The lines kept for `/rosout` while no publisher is attached: (severity, message) (for
    /// tests).
    #[cfg(test)]
    pub fn kept_lines(&self) -> Vec<(Level, String)> {
        let levels = [
            Level::Debug,
            Level::Info,
            Level::Warn,
            Level::Error,
            Level::Fatal,
        ];
        let inner = self.inner.lock().expect("logger lock");
        inner
            .backlog
            .iter()
            .map(|l| {
                let level = levels.into_iter().find(|v| *v as u8 == l.level);
                (level.unwrap_or(Level::Fatal), l.msg.clone())
            })
            .collect()
    }

    /// Writes one line (use the [`log!`](crate::node::logging) macro, which fills in where).
    pub fn write(&self, level: Level, file: &str, function: &str, line: u32, msg: &str) {
        if !self.enabled(level) {
            return;
        }
        let now = SystemTime::now()
            .duration_since(SystemTime::UNIX_EPOCH)
            .unwrap_or_default();
        eprintln!(
            "[{}] [{}.{:09}] [{}]: {msg}",
            level.name(),
            now.as_secs(),
            now.subsec_nanos(),
            self.name
        );
        let record = Log {
            stamp: Time {
                sec: i32::try_from(now.as_secs()).unwrap_or(i32::MAX),
                nanosec: now.subsec_nanos(),
            },
            level: level as u8,
            name: self.name.to_string(),
            msg: msg.to_string(),
            file: file.to_string(),
            function: function.to_string(),
            line,
        };
        let Ok(mut inner) = self.inner.lock() else {
            return;
        };
        match &inner.rosout {
            Some(publisher) => {
                let _ = publisher.publish(record);
            }
            None if inner.backlog.len() < ROSOUT_DEPTH => inner.backlog.push(record),
            None => {}
        }
    }
}

/// The path of the function this is expanded in (closures and async blocks named by the
/// function around them).
#[macro_export]
#[doc(hidden)]
macro_rules! sd_function_name {
    () => {{
        fn here() {}
        fn name_of<T>(_: T) -> &'static str {
            std::any::type_name::<T>()
        }
        let mut name = name_of(here).strip_suffix("::here").unwrap_or("");
        while let Some(outer) = name.strip_suffix("::{{closure}}") {
            name = outer;
        }
        name
    }};
}

/// `log!(logger, Warn, "format", args…)`: one line at that level, with this file, function and
/// line; the message is formatted only if the level is enabled.
macro_rules! log {
    ($logger:expr, $level:ident, $($arg:tt)+) => {{
        let logger = &$logger;
        let level = $crate::node::logging::Level::$level;
        if logger.enabled(level) {
            logger.write(level, file!(), $crate::sd_function_name!(), line!(), &format!($($arg)+));
        }
    }};
}
pub(crate) use log;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logger_names_are_rcl_names() {
        assert_eq!(logger_name("/", "spatial_dynamics"), "spatial_dynamics");
        assert_eq!(
            logger_name("/robot1", "spatial_dynamics"),
            "robot1.spatial_dynamics"
        );
        assert_eq!(logger_name("/a/b/", "n"), "a.b.n");
    }

    #[test]
    fn levels_follow_the_most_specific_setting() {
        let name = "robot1.spatial_dynamics";
        assert_eq!(level_for(name, &[]), Level::Info);
        let warn = |l: Option<&str>| (l.map(str::to_string), Level::Warn);
        let debug = |l: Option<&str>| (l.map(str::to_string), Level::Debug);
        assert_eq!(level_for(name, &[warn(None)]), Level::Warn);
        assert_eq!(
            level_for(name, &[warn(None), debug(Some(name))]),
            Level::Debug
        );
        assert_eq!(
            level_for(name, &[debug(Some(name)), warn(None)]),
            Level::Debug
        );
        assert_eq!(level_for(name, &[debug(Some("robot1"))]), Level::Debug);
        assert_eq!(
            level_for(name, &[warn(Some(name)), debug(Some("robot1"))]),
            Level::Warn
        );
        assert_eq!(level_for(name, &[debug(Some("robot"))]), Level::Info);
        assert_eq!(level_for(name, &[debug(Some("other"))]), Level::Info);
        assert_eq!(Level::parse("WARN"), Ok(Level::Warn));
        assert!(Level::parse("loud").unwrap_err().contains("loud"));
    }

    #[test]
    fn lines_below_the_level_are_not_kept_and_the_function_is_named() {
        let logger = Logger::new("n", Level::Warn);
        log!(logger, Info, "not kept {}", 1);
        log!(logger, Warn, "kept {}", 2);
        let inner = logger.inner.lock().unwrap();
        assert_eq!(inner.backlog.len(), 1);
        let line = &inner.backlog[0];
        assert_eq!((line.level, line.msg.as_str()), (30, "kept 2"));
        assert!(line.file.ends_with("logging.rs"), "{}", line.file);
        assert!(
            line.function
                .ends_with("tests::lines_below_the_level_are_not_kept_and_the_function_is_named"),
            "{}",
            line.function
        );
    }
}
