//! ROS 2 bags: MCAP (the `mcap` crate's streaming reader, chunks
//! decompressed one at a time) and sqlite3 (`rusqlite`, rows iterated in
//! storage order), `sensor_msgs/msg/JointState` decoded by [`super::cdr`].

use super::cdr::{decode_joint_state, JointState, JOINT_STATE};
use super::{BagStamps, ColumnUse, Decimal, LogFormat, LogRead, LogReport, LogSpec, Samples, StepStats};
use crate::error::{Error, Result};
use crate::robot::Robot;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The longest MCAP record accepted (bytes): a corrupt length field above it
/// is an error, not an allocation. rosbag2 writes chunks of about 1 MB.
const MCAP_RECORD_LIMIT: usize = 256 << 20;

/// The storage of a bag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Storage {
    Mcap,
    Sqlite3,
}

impl Storage {
    fn name(self) -> &'static str {
        match self {
            Storage::Mcap => "mcap",
            Storage::Sqlite3 => "sqlite3",
        }
    }
}

/// The files of a bag, in order.
struct BagFiles {
    storage: Storage,
    files: Vec<PathBuf>,
}

/// `metadata.yaml` of a bag folder (the fields read here; rosbag2 writes more).
#[derive(serde::Deserialize)]
struct Metadata {
    rosbag2_bagfile_information: MetadataInfo,
}

#[derive(serde::Deserialize)]
struct MetadataInfo {
    #[serde(default)]
    storage_identifier: String,
    #[serde(default)]
    relative_file_paths: Vec<String>,
    #[serde(default)]
    compression_format: String,
    #[serde(default)]
    compression_mode: String,
}

const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";
const SQLITE_MAGIC: &[u8] = b"SQLite format 3\0";

fn storage_of_file(path: &Path) -> Result<Storage> {
    use std::io::Read;
    let mut head = [0u8; 16];
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let n = f.read(&mut head).map_err(|e| Error::io(path, e))?;
    if head[..n].starts_with(MCAP_MAGIC) {
        Ok(Storage::Mcap)
    } else if head[..n].starts_with(SQLITE_MAGIC) {
        Ok(Storage::Sqlite3)
    } else {
        Err(Error::parse(
            path,
            "not a ROS 2 bag file: neither MCAP (starts with \\x89MCAP0) nor sqlite3 (starts with \"SQLite format 3\"); give the bag folder, its .mcap or its .db3 file",
        ))
    }
}

/// The storage and files of the bag at `path` (a folder with
/// `metadata.yaml`, a folder of `.mcap`/`.db3` files, or one file).
fn locate(path: &Path) -> Result<BagFiles> {
    if path.is_file() {
        return Ok(BagFiles {
            storage: storage_of_file(path)?,
            files: vec![path.to_path_buf()],
        });
    }
    if !path.is_dir() {
        return Err(Error::io(path, std::io::Error::new(std::io::ErrorKind::NotFound, "no such bag file or folder")));
    }
    let meta_path = path.join("metadata.yaml");
    if meta_path.is_file() {
        let text = crate::io::read_to_string_bounded(&meta_path, 16 << 20)?;
        let meta: Metadata = serde_norway::from_str(&text).map_err(|e| Error::parse(&meta_path, format!("not a rosbag2 metadata file: {e}")))?;
        let info = meta.rosbag2_bagfile_information;
        if !info.compression_mode.is_empty() && !info.compression_mode.eq_ignore_ascii_case("none") {
            return Err(Error::invalid(
                meta_path.display().to_string(),
                "compression_mode",
                format!(
                    "the bag is compressed per {} with {}: decompress it first (ros2 bag convert, or rosbags-convert), or record with MCAP chunk compression, which is read directly",
                    info.compression_mode.to_lowercase(),
                    info.compression_format
                ),
            ));
        }
        let storage = match info.storage_identifier.as_str() {
            "mcap" => Storage::Mcap,
            "sqlite3" => Storage::Sqlite3,
            other => {
                return Err(Error::invalid(
                    meta_path.display().to_string(),
                    "storage_identifier",
                    format!("expected mcap or sqlite3, found `{other}`"),
                ))
            }
        };
        if info.relative_file_paths.is_empty() {
            return Err(Error::invalid(meta_path.display().to_string(), "relative_file_paths", "the bag lists no files"));
        }
        let mut files = Vec::new();
        for f in &info.relative_file_paths {
            let p = path.join(f);
            if !p.is_file() {
                return Err(Error::io(
                    &p,
                    std::io::Error::new(std::io::ErrorKind::NotFound, "listed in metadata.yaml but not found"),
                ));
            }
            files.push(p);
        }
        return Ok(BagFiles { storage, files });
    }
    let rd = std::fs::read_dir(path).map_err(|e| Error::io(path, e))?;
    let mut files: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "mcap" || e == "db3"))
        .collect();
    files.sort();
    let Some(first) = files.first() else {
        return Err(Error::io(
            path,
            std::io::Error::other("is a folder without metadata.yaml and without .mcap or .db3 files: not a ROS 2 bag"),
        ));
    };
    let ext = first.extension().map(|e| e.to_os_string());
    if files.iter().any(|f| f.extension().map(|e| e.to_os_string()) != ext) {
        return Err(Error::io(path, std::io::Error::other("holds both .mcap and .db3 files: give one bag file")));
    }
    Ok(BagFiles {
        storage: if ext.is_some_and(|e| e == "mcap") { Storage::Mcap } else { Storage::Sqlite3 },
        files,
    })
}

/// One message of a bag.
struct Msg<'a> {
    file: &'a Path,
    topic: &'a str,
    msg_type: &'a str,
    encoding: &'a str,
    /// The recorder's receive time (ns since the epoch).
    log_time: i64,
    data: &'a [u8],
}

/// A topic of a bag: type, serialisation and message count.
#[derive(Debug, Clone, Default)]
struct TopicCount {
    msg_type: String,
    messages: u64,
}

/// Calls `f` on every message of the bag whose topic and type `want`
/// accepts, in storage order; returns every topic with its message count.
fn visit(bf: &BagFiles, want: &dyn Fn(&str, &str) -> bool, f: &mut dyn FnMut(Msg) -> Result<()>) -> Result<BTreeMap<String, TopicCount>> {
    let mut topics: BTreeMap<String, TopicCount> = BTreeMap::new();
    for file in &bf.files {
        match bf.storage {
            Storage::Mcap => visit_mcap(file, want, f, &mut topics)?,
            Storage::Sqlite3 => visit_sqlite(file, want, f, &mut topics)?,
        }
    }
    Ok(topics)
}

fn visit_mcap(file: &Path, want: &dyn Fn(&str, &str) -> bool, f: &mut dyn FnMut(Msg) -> Result<()>, topics: &mut BTreeMap<String, TopicCount>) -> Result<()> {
    let fh = std::fs::File::open(file).map_err(|e| Error::io(file, e))?;
    let opts = mcap::sans_io::LinearReaderOptions::default()
        .with_record_length_limit(MCAP_RECORD_LIMIT)
        .with_prevalidate_chunk_crcs(true);
    let reader = mcap::io::MessageReader::new_with_options(std::io::BufReader::with_capacity(1 << 16, fh), opts);
    for (count, m) in reader.enumerate() {
        let m = m.map_err(|e| Error::parse(file, format!("MCAP: {e} (after {count} messages)")))?;
        let ch = &m.channel;
        let msg_type = ch.schema.as_ref().map_or("", |s| s.name.as_str());
        let t = topics.entry(ch.topic.clone()).or_default();
        if t.messages == 0 {
            t.msg_type = msg_type.to_string();
        }
        t.messages += 1;
        if want(&ch.topic, msg_type) {
            f(Msg {
                file,
                topic: &ch.topic,
                msg_type,
                encoding: &ch.message_encoding,
                log_time: i64::try_from(m.log_time).unwrap_or(i64::MAX),
                data: &m.data,
            })?;
        }
    }
    Ok(())
}

fn visit_sqlite(file: &Path, want: &dyn Fn(&str, &str) -> bool, f: &mut dyn FnMut(Msg) -> Result<()>, topics: &mut BTreeMap<String, TopicCount>) -> Result<()> {
    use rusqlite::{Connection, OpenFlags};
    let e = |e: rusqlite::Error| Error::parse(file, format!("sqlite3 bag: {e}"));
    let db = Connection::open_with_flags(file, OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX).map_err(e)?;
    // (id, name, type, serialization_format)
    let mut list: Vec<(i64, String, String, String)> = Vec::new();
    {
        let mut st = db
            .prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id")
            .map_err(|err| Error::parse(file, format!("not a rosbag2 sqlite3 file (no topics table): {err}")))?;
        let rows = st.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?))).map_err(e)?;
        for r in rows {
            list.push(r.map_err(e)?);
        }
    }
    {
        let mut st = db.prepare("SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id").map_err(e)?;
        let rows = st.query_map([], |r| Ok((r.get::<_, i64>(0)?, r.get::<_, i64>(1)?))).map_err(e)?;
        for r in rows {
            let (id, n) = r.map_err(e)?;
            if let Some((_, name, ty, _)) = list.iter().find(|t| t.0 == id) {
                let t = topics.entry(name.clone()).or_default();
                t.msg_type = ty.clone();
                t.messages += u64::try_from(n).unwrap_or(0);
            }
        }
    }
    let wanted: Vec<&(i64, String, String, String)> = list.iter().filter(|t| want(&t.1, &t.2)).collect();
    if wanted.is_empty() {
        return Ok(());
    }
    let ids: Vec<String> = wanted.iter().map(|t| t.0.to_string()).collect();
    let sql = format!(
        "SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN ({}) ORDER BY id",
        ids.join(",")
    );
    let mut st = db.prepare(&sql).map_err(e)?;
    let mut rows = st.query([]).map_err(e)?;
    while let Some(r) = rows.next().map_err(e)? {
        let id: i64 = r.get(0).map_err(e)?;
        let ts: i64 = r.get(1).map_err(e)?;
        let data = r.get_ref(2).map_err(e)?;
        let data = data.as_blob().map_err(|err| Error::parse(file, format!("sqlite3 bag: message data: {err}")))?;
        if let Some(t) = wanted.iter().find(|t| t.0 == id) {
            f(Msg {
                file,
                topic: &t.1,
                msg_type: &t.2,
                encoding: &t.3,
                log_time: ts,
                data,
            })?;
        }
    }
    Ok(())
}

/// The topic name as given (`joint_states` matches `/joint_states`).
fn same_topic(a: &str, b: &str) -> bool {
    a.trim_start_matches('/') == b.trim_start_matches('/')
}

/// The state of one JointState topic while it is read.
struct TopicRead {
    samples: Option<Samples>,
    /// The message's names the `index` was built for.
    names: Vec<String>,
    /// Per robot joint, its position in the message's arrays.
    index: Vec<usize>,
    /// Names in the messages that are not robot joints.
    extra: std::collections::BTreeSet<String>,
    messages: usize,
    error: Option<Error>,
}

impl TopicRead {
    fn new() -> TopicRead {
        TopicRead {
            samples: None,
            names: Vec::new(),
            index: Vec::new(),
            extra: Default::default(),
            messages: 0,
            error: None,
        }
    }

    /// Adds one message; an error message (text) names what is wrong in it.
    fn add(&mut self, m: &Msg, wanted: &[String], stamps: BagStamps) -> std::result::Result<(), String> {
        if m.encoding != "cdr" {
            return Err(format!("message encoding `{}`: expected cdr (ROS 2's serialisation)", m.encoding));
        }
        let js: JointState = decode_joint_state(m.data)?;
        let nn = js.name.len();
        if js.name != self.names {
            let mut missing = Vec::new();
            let mut index = Vec::with_capacity(wanted.len());
            for w in wanted {
                match js.name.iter().position(|n| n == w) {
                    Some(i) => index.push(i),
                    None => missing.push(format!("`{w}`")),
                }
            }
            if !missing.is_empty() {
                return Err(format!(
                    "joint(s) {} of the robot not in the message, which names [{}]: record them, or map the robot's joints to the logged names with joints = [...] in the log spec",
                    missing.join(", "),
                    js.name.join(", ")
                ));
            }
            for (i, n) in js.name.iter().enumerate() {
                if js.name[..i].contains(n) {
                    return Err(format!("joint `{n}` named twice in the message"));
                }
                if !wanted.contains(n) {
                    self.extra.insert(n.clone());
                }
            }
            self.index = index;
            self.names = js.name.clone();
        }
        for (field, len, may_be_empty) in [
            ("position", js.position.len(), false),
            ("velocity", js.velocity.len(), true),
            ("effort", js.effort.len(), true),
        ] {
            if len != nn && !(may_be_empty && len == 0) {
                return Err(format!(
                    "{field} has {len} values for {nn} joint names: JointState arrays are as long as name{}",
                    if may_be_empty { " or empty" } else { "" }
                ));
            }
        }
        if js.effort.is_empty() {
            return Err("no effort values: idexp needs the joint torques (JointState effort, N·m or N)".into());
        }
        let ns = match stamps {
            BagStamps::Header => js.header.stamp.nanoseconds()?,
            BagStamps::Receive => m.log_time,
        };
        let has_vel = !js.velocity.is_empty();
        let s = self.samples.get_or_insert_with(|| Samples::new(m.file, has_vel, false));
        if s.rep.qd.is_some() != has_vel {
            return Err(format!(
                "{} velocity values, unlike the first message: velocity is logged in every message or in none",
                if has_vel { "has" } else { "has no" }
            ));
        }
        s.time(Decimal::from_int(i128::from(ns), -9), || stamp_text(ns))?;
        let pick = |v: &[f64], field: &str| -> std::result::Result<Vec<f64>, String> {
            self.index
                .iter()
                .zip(wanted)
                .map(|(&i, w)| {
                    let x = v[i];
                    if x.is_finite() {
                        Ok(x)
                    } else {
                        Err(format!("joint `{w}`: {field} = {x}, expected a finite number"))
                    }
                })
                .collect()
        };
        let q = pick(&js.position, "position")?;
        let tau = pick(&js.effort, "effort")?;
        let qd = if has_vel { Some(pick(&js.velocity, "velocity")?) } else { None };
        let s = self.samples.as_mut().ok_or("no samples")?;
        s.rep.q.push(q);
        s.rep.tau.push(tau);
        if let (Some(v), Some(x)) = (s.rep.qd.as_mut(), qd) {
            v.push(x);
        }
        Ok(())
    }
}

/// `sec.nanosec s since the epoch`.
fn stamp_text(ns: i64) -> String {
    let sign = if ns < 0 { "-" } else { "" };
    let a = ns.unsigned_abs();
    format!("{sign}{}.{:09} s since the epoch", a / 1_000_000_000, a % 1_000_000_000)
}

fn topic_list(topics: &BTreeMap<String, TopicCount>) -> String {
    if topics.is_empty() {
        return "none".into();
    }
    topics
        .iter()
        .map(|(n, t)| format!("{n} ({}, {} messages)", t.msg_type, t.messages))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Reads a bag (see the module documentation of [`super`]).
pub(super) fn read(path: &Path, robot: &Robot, spec: &LogSpec) -> Result<LogRead> {
    let bf = locate(path)?;
    let wanted: Vec<String> = match &spec.joints {
        Some(j) => {
            if j.len() != robot.dof() {
                return Err(Error::invalid(
                    format!("log spec for {}", path.display()),
                    "joints",
                    format!(
                        "{} names for a robot with {} joints: give the logged name of each robot joint, in the robot's order",
                        j.len(),
                        robot.dof()
                    ),
                ));
            }
            j.clone()
        }
        None => robot.joints.iter().map(|j| j.name.clone()).collect(),
    };
    let stamps = spec.stamps.unwrap_or_default();
    let chosen = spec.topic.clone();
    let mut reads: BTreeMap<String, TopicRead> = BTreeMap::new();
    let want = |topic: &str, ty: &str| match &chosen {
        Some(c) => same_topic(c, topic),
        None => ty == JOINT_STATE,
    };
    let topics = visit(&bf, &want, &mut |m: Msg| {
        let st = reads.entry(m.topic.to_string()).or_insert_with(TopicRead::new);
        st.messages += 1;
        if st.error.is_some() {
            return Ok(());
        }
        if m.msg_type != JOINT_STATE {
            st.error = Some(Error::invalid(
                path.display().to_string(),
                "topic",
                format!("topic {} has type {}: expected {JOINT_STATE}", m.topic, m.msg_type),
            ));
            return Ok(());
        }
        if let Err(msg) = st.add(&m, &wanted, stamps) {
            let e = Error::parse(m.file, format!("message {} on topic {}: {msg}", st.messages, m.topic));
            if chosen.is_some() {
                // the topic was chosen: stop at its first bad message
                return Err(e);
            }
            st.error = Some(e);
        }
        Ok(())
    })?;
    let joint_topics: Vec<&String> = topics.iter().filter(|(_, t)| t.msg_type == JOINT_STATE).map(|(n, _)| n).collect();
    let topic = match &chosen {
        Some(c) => match topics.keys().find(|t| same_topic(c, t)) {
            Some(t) => t.clone(),
            None => {
                return Err(Error::invalid(
                    path.display().to_string(),
                    "topic",
                    format!("no topic {c} in the bag; its topics: {}", topic_list(&topics)),
                ))
            }
        },
        None => match joint_topics.as_slice() {
            [one] => (*one).clone(),
            [] => {
                return Err(Error::invalid(
                    path.display().to_string(),
                    "topic",
                    format!("the bag has no {JOINT_STATE} topic; its topics: {}", topic_list(&topics)),
                ))
            }
            many => {
                return Err(Error::invalid(
                    path.display().to_string(),
                    "topic",
                    format!(
                        "the bag has {} {JOINT_STATE} topics: {}; choose one with topic = \"…\" in the log spec",
                        many.len(),
                        many.iter()
                            .map(|t| format!("{t} ({} messages)", topics[*t].messages))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                ))
            }
        },
    };
    let st = reads.remove(&topic).unwrap_or_else(TopicRead::new);
    if let Some(e) = st.error {
        return Err(e);
    }
    let Some(samples) = st.samples else {
        return Err(Error::parse(path, format!("topic {topic} has no messages")));
    };
    let (rep, start, span, steps) = samples.finish("messages")?;
    let mut columns = vec![ColumnUse {
        column: "t".into(),
        source: match stamps {
            BagStamps::Header => "header.stamp (sec, nanosec)".into(),
            BagStamps::Receive => "the recorder's receive time".into(),
        },
    }];
    for (field, p) in [("position", "q"), ("velocity", "qd"), ("effort", "tau")] {
        if p == "qd" && rep.qd.is_none() {
            continue;
        }
        columns.extend(wanted.iter().enumerate().map(|(j, w)| ColumnUse {
            column: format!("{p}{}", j + 1),
            source: format!("{w} {field}"),
        }));
    }
    let mut ignored = Vec::new();
    if !st.extra.is_empty() {
        ignored.push(format!("joints not in the robot: {}", st.extra.iter().cloned().collect::<Vec<_>>().join(", ")));
    }
    let others: Vec<String> = topics
        .iter()
        .filter(|(n, _)| **n != topic)
        .map(|(n, t)| format!("{n} ({}, {} messages)", t.msg_type, t.messages))
        .collect();
    if !others.is_empty() {
        ignored.push(format!("other topics: {}", others.join(", ")));
    }
    Ok(LogRead {
        report: LogReport {
            file: path.to_path_buf(),
            format: LogFormat::Bag,
            source: format!(
                "ROS 2 bag, {} storage ({} file{}), topic {topic} ({JOINT_STATE}, {} messages)",
                bf.storage.name(),
                bf.files.len(),
                if bf.files.len() == 1 { "" } else { "s" },
                st.messages
            ),
            samples: rep.len(),
            start,
            span,
            steps,
            columns,
            torque: "JointState effort (joint torques, N·m or N)".into(),
            torque_per_ampere: None,
            ignored,
        },
        rep,
    })
}

/// One topic of a bag, as [`bag_info`] reports it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TopicInfo {
    /// Topic name.
    pub topic: String,
    /// Message type.
    pub msg_type: String,
    /// Number of messages.
    pub messages: u64,
    /// For JointState topics: the joint names of the first message.
    pub joint_names: Option<Vec<String>>,
    /// For JointState topics: the first header stamp.
    pub start: Option<String>,
    /// For JointState topics: header-stamp span (s).
    pub span: Option<f64>,
    /// For JointState topics: steps between increasing header stamps.
    pub steps: Option<StepStats>,
    /// For JointState topics: stamps that do not increase, messages that do not decode.
    pub problems: Vec<String>,
}

/// What a bag holds (`idexp log info`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BagInfo {
    /// The bag folder or file.
    pub path: PathBuf,
    /// `mcap` or `sqlite3`.
    pub storage: String,
    /// The storage files, in order.
    pub files: Vec<PathBuf>,
    /// Every topic.
    pub topics: Vec<TopicInfo>,
}

impl BagInfo {
    /// A few lines for the terminal.
    pub fn text(&self) -> String {
        let mut s = format!("{}: ROS 2 bag, {} storage, {} file(s)\n", self.path.display(), self.storage, self.files.len());
        for t in &self.topics {
            s += &format!("  {} ({}): {} messages\n", t.topic, t.msg_type, t.messages);
            if let Some(n) = &t.joint_names {
                s += &format!("    joints: {}\n", n.join(", "));
            }
            if let (Some(start), Some(span)) = (&t.start, t.span) {
                s += &format!("    header stamps from {start}, span {span:.6} s\n");
            }
            if let Some(st) = &t.steps {
                s += &format!("    {}\n", st.text());
            }
            for p in &t.problems {
                s += &format!("    problem: {p}\n");
            }
        }
        s
    }
}

/// The topics, message counts, joint names, time spans and rates of a bag.
pub fn bag_info(path: &Path) -> Result<BagInfo> {
    let bf = locate(path)?;
    #[derive(Default)]
    struct Acc {
        names: Option<Vec<String>>,
        first: Option<i64>,
        last: Option<i64>,
        steps: Vec<f64>,
        bad_order: usize,
        bad_decode: Option<String>,
    }
    let mut acc: BTreeMap<String, Acc> = BTreeMap::new();
    let topics = visit(&bf, &|_, ty| ty == JOINT_STATE, &mut |m: Msg| {
        let a = acc.entry(m.topic.to_string()).or_default();
        match decode_joint_state(m.data).and_then(|js| Ok((js.header.stamp.nanoseconds()?, js.name))) {
            Ok((ns, names)) => {
                if a.names.is_none() {
                    a.names = Some(names);
                }
                match a.last {
                    Some(p) if ns <= p => a.bad_order += 1,
                    Some(p) => {
                        a.steps.push((ns - p) as f64 / 1e9);
                        a.last = Some(ns);
                    }
                    None => {
                        a.first = Some(ns);
                        a.last = Some(ns);
                    }
                }
            }
            Err(e) => {
                if a.bad_decode.is_none() {
                    a.bad_decode = Some(e);
                }
            }
        }
        Ok(())
    })?;
    let infos = topics
        .into_iter()
        .map(|(topic, t)| {
            let a = acc.remove(&topic).unwrap_or_default();
            let mut problems = Vec::new();
            if a.bad_order > 0 {
                problems.push(format!("{} header stamps not after the previous one", a.bad_order));
            }
            if let Some(e) = a.bad_decode {
                problems.push(format!("messages that do not decode, the first: {e}"));
            }
            let steps = StepStats::from_steps(a.steps);
            TopicInfo {
                joint_names: a.names,
                start: a.first.map(stamp_text),
                span: a.first.zip(a.last).map(|(f, l)| (l - f) as f64 / 1e9),
                steps,
                problems,
                topic,
                msg_type: t.msg_type,
                messages: t.messages,
            }
        })
        .collect();
    Ok(BagInfo {
        path: path.to_path_buf(),
        storage: bf.storage.name().into(),
        files: bf.files,
        topics: infos,
    })
}
