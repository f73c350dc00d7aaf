//! Multistart: results do not depend on the thread count; a run resumed after
//! an interruption (including a line cut by a kill) writes the same final file
//! as an uninterrupted run; shards merged equal a single run; logs of another
//! design are refused.

use idexp::frf::pipeline::{self, FitOptions};
use idexp::frf::Shard;
use std::path::{Path, PathBuf};

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// A small version of the shipped design: 2 positions, lines up to 41 Hz, 6 starts, 40 iterations.
fn small_design(dir: &Path) -> PathBuf {
    let s = std::fs::read_to_string(root("designs/elastic_industrial6.toml")).unwrap();
    let s = s.replace("robots/industrial6.toml", root("designs/robots/industrial6.toml").to_str().unwrap());
    let i = s.find("positions = [\n").unwrap() + "positions = [\n".len();
    let j = i + s[i..].find("]\n\n").unwrap();
    let rows: Vec<&str> = s[i..j].lines().take(2).collect();
    let s = format!("{}{}\n{}", &s[..i], rows.join("\n"), &s[j..]);
    let s = s
        .replace("band = [2.0, 150.0]", "band = [2.0, 41.0]")
        .replace("band = [3.0, 150.0]", "band = [3.0, 41.0]")
        .replace("starts = 100", "starts = 6")
        .replace("max_iter = 200", "max_iter = 40");
    std::fs::create_dir_all(dir).unwrap();
    let p = dir.join("small.toml");
    std::fs::write(&p, s).unwrap();
    pipeline::frf(&p, Some(dir), &idexp::optim::Control::new()).unwrap();
    p
}

fn opts(out: &Path) -> FitOptions {
    FitOptions {
        data: Some(out.join("frf/frf.json")),
        out: Some(out.to_path_buf()),
        ..Default::default()
    }
}

/// `pipeline::fit` of design `p` on the FRF file `data` into `out`, on a rayon pool of `threads` threads.
fn fit_on_threads(threads: usize, p: &Path, data: &Path, out: &Path) -> pipeline::FitRun {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        pipeline::fit(
            p,
            &FitOptions {
                data: Some(data.to_path_buf()),
                ..opts(out)
            },
            &idexp::optim::Control::new(),
        )
    })
    .unwrap()
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap()
}

#[test]
fn thread_count_resume_and_shards_give_the_same_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = small_design(dir.path());
    let data = dir.path().join("frf/frf.json");

    // reference: one run on 2 threads
    let a = dir.path().join("a");
    let ra = fit_on_threads(2, &p, &data, &a);
    assert!(!ra.interrupted && ra.report.is_some());
    let ref_log = read(&ra.dir.join("starts.jsonl"));
    let ref_fit = read(&ra.dir.join("fit.json"));
    assert_eq!(ref_log.lines().count(), 6);

    // one thread
    let b = dir.path().join("b");
    let rb = fit_on_threads(1, &p, &data, &b);
    assert_eq!(read(&rb.dir.join("starts.jsonl")), ref_log, "1 thread vs 2 threads");
    assert_eq!(read(&rb.dir.join("fit.json")), ref_fit);

    // resume: a log holding starts 4 and 1 (out of order, as threads finish) and a cut line
    let c = dir.path().join("c");
    let lines: Vec<&str> = ref_log.lines().collect();
    let fitdir = ra.dir.file_name().unwrap().to_owned();
    std::fs::create_dir_all(c.join(&fitdir)).unwrap();
    let partial = format!("{}\n{}\n{}", lines[4], lines[1], &lines[2][..lines[2].len() / 2]);
    std::fs::write(c.join(&fitdir).join("starts.jsonl"), partial).unwrap();
    let rc = pipeline::fit(
        &p,
        &FitOptions {
            data: Some(data.clone()),
            ..opts(&c)
        },
        &idexp::optim::Control::new(),
    )
    .unwrap();
    assert_eq!(rc.records.len(), 6);
    assert_eq!(read(&rc.dir.join("starts.jsonl")), ref_log, "resumed run");
    assert_eq!(read(&rc.dir.join("fit.json")), ref_fit);

    // a run with fewer starts is continued by one with more
    let g = dir.path().join("g");
    let rg = pipeline::fit(
        &p,
        &FitOptions {
            data: Some(data.clone()),
            starts: Some(3),
            ..opts(&g)
        },
        &idexp::optim::Control::new(),
    )
    .unwrap();
    assert_eq!(rg.records.len(), 3);
    let rg = pipeline::fit(
        &p,
        &FitOptions {
            data: Some(data.clone()),
            ..opts(&g)
        },
        &idexp::optim::Control::new(),
    )
    .unwrap();
    assert_eq!(read(&rg.dir.join("starts.jsonl")), ref_log, "3 starts, then 6");

    // shards 0/3, 1/3, 2/3 then merge
    let s = dir.path().join("s");
    let mut shard_files = Vec::new();
    for i in 0..3 {
        let r = pipeline::fit(
            &p,
            &FitOptions {
                data: Some(data.clone()),
                shard: Some(Shard { index: i, count: 3 }),
                ..opts(&s)
            },
            &idexp::optim::Control::new(),
        )
        .unwrap();
        assert!(r.report.is_none());
        assert_eq!(r.records.len(), 2);
        shard_files.push(r.log);
    }
    // merging an incomplete set is refused, naming the missing starts
    let e = pipeline::merge(&shard_files[..2], None).unwrap_err().to_string();
    assert!(e.contains("missing"), "{e}");
    let (_, mdir) = pipeline::merge(&shard_files, None).unwrap();
    assert_eq!(read(&mdir.join("starts.jsonl")), ref_log, "merged shards");
    assert_eq!(read(&mdir.join("fit.json")), ref_fit);
    let figures = mdir.join("costs.svg").exists() && mdir.join("bode_pos1.svg").exists() && mdir.join("phase_pos2.svg").exists();
    assert_eq!(figures, cfg!(feature = "plots"), "figures are written with (and only with) the `plots` feature");

    // a log from another design is refused
    let other = small_design(&dir.path().join("other"));
    let txt = read(&other).replace("seed = 2026", "seed = 7");
    std::fs::write(&other, txt).unwrap();
    let e = pipeline::fit(
        &other,
        &FitOptions {
            data: Some(data.clone()),
            ..opts(&c)
        },
        &idexp::optim::Control::new(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("another design"), "{e}");
}

#[test]
fn shard_parsing_and_start_points() {
    assert_eq!(Shard::parse("1/4").unwrap(), Shard { index: 1, count: 4 });
    assert_eq!(Shard::parse("1/4").unwrap().indices(10), vec![1, 5, 9]);
    for bad in ["4/4", "x/2", "1", "1/0", "-1/3"] {
        assert!(Shard::parse(bad).unwrap_err().to_string().contains("shard"), "{bad}");
    }
    // start points: θ·10^φ with |φ| ≤ spread, reproducible per index
    let th = vec![1.0, 10.0, 1e5];
    let a = idexp::frf::multistart::start_point(&th, 1.0, 3, 5);
    assert_eq!(a, idexp::frf::multistart::start_point(&th, 1.0, 3, 5));
    assert_ne!(a, idexp::frf::multistart::start_point(&th, 1.0, 3, 6));
    for (x, t) in a.iter().zip(&th) {
        let phi = (x / t).log10();
        assert!(phi.abs() <= 1.0 + 1e-12);
    }
    // the spread of φ covers [−1, 1]
    let phis: Vec<f64> = (0..400).map(|l| idexp::frf::multistart::start_point(&[1.0], 1.0, 3, l)[0].log10()).collect();
    let mean = phis.iter().sum::<f64>() / phis.len() as f64;
    let var = phis.iter().map(|p| (p - mean).powi(2)).sum::<f64>() / phis.len() as f64;
    assert!(mean.abs() < 0.1 && (var - 1.0 / 3.0).abs() < 0.06, "U[−1,1]: mean {mean}, var {var}");
}
