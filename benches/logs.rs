//! Reading robot logs: a 10-minute, 500 Hz ROS 2 bag of
//! `sensor_msgs/msg/JointState` (300,000 messages, 7 joints of which the
//! UR5 uses 6) in MCAP (uncompressed and zstd chunks) and sqlite3 storage,
//! read into a `Repetition` by `idexp::data::logs::read_log` (issue 37:
//! ≤ 2 s). The bags are written here for the benchmark only, with the mcap
//! crate's writer and rusqlite (rosbag2's sqlite3 schema).
//!
//! Besides the timings it prints the peak resident memory added while one
//! read runs, for 60,000 and 300,000 messages, next to the heap of the
//! samples returned: the rest (the reader's buffers and the transient of
//! growing the sample vectors) is what reading costs beyond its result
//! (Linux: peak reset through /proc/self/clear_refs, read from
//! /proc/self/status VmHWM; freed memory returned by malloc_trim between
//! measurements).

use criterion::{criterion_group, criterion_main, Criterion};
use idexp::data::logs::cdr::{encode_joint_state, Header, JointState, Time};
use idexp::data::logs::{read_log, LogFormat, LogSpec};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

const NAMES: [&str; 7] = [
    "elbow_joint",
    "shoulder_pan_joint",
    "wrist_3_joint",
    "gripper_finger_joint",
    "shoulder_lift_joint",
    "wrist_1_joint",
    "wrist_2_joint",
];
const EPOCH_NS: i64 = 1_733_400_000_000_000_000;

/// Message k at 500 Hz with 0–40 µs of stamp jitter.
fn message(k: usize) -> (i64, Vec<u8>) {
    let ns = EPOCH_NS + k as i64 * 2_000_000 + ((k * 7919) % 41) as i64 * 1000;
    let x = k as f64 * 0.002;
    let m = JointState {
        header: Header {
            stamp: Time {
                sec: (ns / 1_000_000_000) as i32,
                nanosec: (ns % 1_000_000_000) as u32,
            },
            frame_id: String::new(),
        },
        name: NAMES.iter().map(|s| s.to_string()).collect(),
        position: (0..7).map(|j| (x + j as f64).sin()).collect(),
        velocity: (0..7).map(|j| (x + j as f64).cos()).collect(),
        effort: (0..7).map(|j| 10.0 * (x * 0.5 + j as f64).sin()).collect(),
    };
    (ns, encode_joint_state(&m).unwrap())
}

fn write_mcap(path: &Path, n: usize, compression: Option<mcap::Compression>) {
    let f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::WriteOptions::new().compression(compression).profile("ros2").create(f).unwrap();
    let schema = w.add_schema("sensor_msgs/msg/JointState", "ros2msg", b"").unwrap();
    let ch = w.add_channel(schema, "/joint_states", "cdr", &BTreeMap::new()).unwrap();
    for k in 0..n {
        let (ns, data) = message(k);
        let h = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: k as u32,
            log_time: ns as u64 + 300_000,
            publish_time: ns as u64 + 300_000,
        };
        w.write_to_known_channel(&h, &data).unwrap();
    }
    w.finish().unwrap();
}

fn write_sqlite(path: &Path, n: usize) {
    let _ = std::fs::remove_file(path);
    let mut db = rusqlite::Connection::open(path).unwrap();
    db.execute_batch(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
         CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, timestamp INTEGER NOT NULL, data BLOB NOT NULL);
         CREATE INDEX timestamp_idx ON messages (timestamp ASC);
         INSERT INTO topics VALUES (1, '/joint_states', 'sensor_msgs/msg/JointState', 'cdr', '');",
    )
    .unwrap();
    let tx = db.transaction().unwrap();
    {
        let mut st = tx.prepare("INSERT INTO messages (topic_id, timestamp, data) VALUES (1, ?1, ?2)").unwrap();
        for k in 0..n {
            let (ns, data) = message(k);
            st.execute(rusqlite::params![ns + 300_000, data]).unwrap();
        }
    }
    tx.commit().unwrap();
}

/// Peak resident memory (kB) since the last reset, and a reset.
fn peak_kb() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    s.lines().find(|l| l.starts_with("VmHWM:"))?.split_whitespace().nth(1)?.parse().ok()
}

fn reset_peak() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

fn memory(robot: &idexp::robot::Robot, path: &Path, what: &str) {
    let spec = LogSpec::new(LogFormat::Bag);
    reset_peak();
    let before = peak_kb();
    let r = read_log(path, robot, &spec).unwrap();
    let after = peak_kb();
    // the heap of the samples returned: t, and per row of q, qd, tau a 24-byte
    // Vec header in the outer vector and a 48-byte allocation (64 with malloc's header)
    let rows = |v: &Vec<Vec<f64>>| v.capacity() * 24 + v.len() * 64;
    let rep = &r.rep;
    let heap = rep.t.capacity() * 8 + rows(&rep.q) + rows(&rep.tau) + rep.qd.as_ref().map_or(0, rows);
    if let (Some(b), Some(a)) = (before, after) {
        let grown = a.saturating_sub(b) * 1024;
        eprintln!(
            "logs/memory {what}: {} messages, peak RSS +{:.1} MB while reading; the returned samples {:.1} MB; the rest {:.1} MB",
            rep.len(),
            grown as f64 / 1e6,
            heap as f64 / 1e6,
            (grown as f64 - heap as f64) / 1e6
        );
    }
    drop(r);
    // give the freed samples back to the system, so the next measurement starts clean
    // SAFETY: malloc_trim only releases free heap memory; no pointer is invalidated
    #[cfg(all(target_os = "linux", feature = "cli"))]
    unsafe {
        libc::malloc_trim(0);
    }
}

fn bench_bags(c: &mut Criterion) {
    let robot = idexp::robot::load(&root("designs/robots/ur5.toml")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let n = 300_000;
    let plain = dir.path().join("plain.mcap");
    let zstd = dir.path().join("zstd.mcap");
    let db3 = dir.path().join("bag.db3");
    write_mcap(&plain, n, None);
    write_mcap(&zstd, n, Some(mcap::Compression::Zstd));
    write_sqlite(&db3, n);
    for (p, name) in [(&plain, "mcap"), (&zstd, "mcap zstd"), (&db3, "sqlite3")] {
        eprintln!("logs/{name}: {} MB", std::fs::metadata(p).unwrap().len() >> 20);
    }
    let small = dir.path().join("small.mcap");
    write_mcap(&small, n / 5, None);
    memory(&robot, &small, "mcap 2 min");
    memory(&robot, &plain, "mcap 10 min");
    let small_db = dir.path().join("small.db3");
    write_sqlite(&small_db, n / 5);
    memory(&robot, &small_db, "sqlite3 2 min");
    memory(&robot, &db3, "sqlite3 10 min");
    let spec = LogSpec::new(LogFormat::Bag);
    let mut g = c.benchmark_group("logs");
    g.sample_size(10).measurement_time(Duration::from_secs(15));
    for (p, name) in [(&plain, "mcap"), (&zstd, "mcap zstd"), (&db3, "sqlite3")] {
        g.bench_function(format!("read_log {name} 300k JointState (10 min at 500 Hz)"), |b| {
            b.iter(|| read_log(p, &robot, &spec).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench_bags);
criterion_main!(benches);
