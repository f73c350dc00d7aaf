//! The 3D preview page (`preview.html`, `idexp view`): in a real browser
//! and against independent computations.
//!
//! The browser test needs headless Chromium (Debian's `chromium`, installed
//! by scripts/setup-system.sh) and fails, never skips, without it. WebGL runs
//! in software (SwiftShader: `--use-angle=swiftshader
//! --enable-unsafe-swiftshader`). Screenshots go to target/preview-test/.

use idexp::preview::{build, read_rows, Motion, PreviewOptions, Setup};
use idexp::robot::collision::PairClass;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn idexp() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_idexp"));
    c.current_dir(root()).env("IDEXP_NO_PROGRESS", "1");
    c
}

/// The output folder of `idexp excite designs/excite_ur5.toml` (run once per test binary).
fn ur5_folder() -> PathBuf {
    static ONCE: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    ONCE.get_or_init(|| {
        let out = root().join("target/preview-test/excite_ur5");
        let st = idexp()
            .args(["excite", "designs/excite_ur5.toml", "--out"])
            .arg(&out)
            .status()
            .expect("run idexp");
        assert!(st.success(), "idexp excite failed: {st}");
        out
    })
    .clone()
}

fn read_json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

/// report.json's least self distance: (pair, distance, time in the delivered trajectory).
fn report_worst_self(dir: &Path) -> (String, f64, f64) {
    let report = read_json(&dir.join("report.json"));
    let coeff = read_json(&dir.join("coefficients.json"));
    let lead_in = coeff["delivered"]["lead_in"]["duration"].as_f64().unwrap_or(0.0);
    let m = report["result"]["margins"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| m["kind"] == "self_collision")
        .min_by(|a, b| a["worst"].as_f64().unwrap().total_cmp(&b["worst"].as_f64().unwrap()))
        .expect("a self-collision margin")
        .clone();
    let name = m["name"].as_str().unwrap();
    let pair = name.trim_start_matches("distance ").split(" ≥ ").next().unwrap().to_string();
    (pair, m["worst"].as_f64().unwrap(), lead_in + m["at"].as_f64().unwrap())
}

fn chromium() -> Command {
    let mut c = Command::new("chromium");
    c.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu-sandbox",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--hide-scrollbars",
        "--window-size=1280,800",
        "--virtual-time-budget=8000",
    ]);
    c
}

/// The page's state (`#idexp-state`) after loading `url` in headless Chromium.
fn page_state(url: &str) -> serde_json::Value {
    let out = chromium()
        .arg("--dump-dom")
        .arg(url)
        .output()
        .unwrap_or_else(|e| panic!("headless Chromium is needed for this test (`chromium`, installed by scripts/setup-system.sh): {e}"));
    assert!(out.status.success(), "chromium --dump-dom failed: {}", String::from_utf8_lossy(&out.stderr));
    let dom = String::from_utf8(out.stdout).unwrap();
    let start = dom.find("<pre id=\"idexp-state\">").expect("the state element") + "<pre id=\"idexp-state\">".len();
    let end = start + dom[start..].find("</pre>").unwrap();
    let text = dom[start..end].replace("&lt;", "<").replace("&gt;", ">").replace("&amp;", "&");
    let err_at = dom.find("id=\"error\">").unwrap() + "id=\"error\">".len();
    assert!(
        dom[err_at..].starts_with("</div>"),
        "the page reports an error: {}",
        &dom[err_at..err_at + 400.min(dom.len() - err_at)]
    );
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("state is not JSON ({e}): {text}"))
}

/// RGB pixels of a screenshot of `url` written to `png`.
fn screenshot(url: &str, png: &Path) -> (usize, usize, Vec<[u8; 3]>) {
    let _ = std::fs::remove_file(png);
    let st = chromium().arg(format!("--screenshot={}", png.display())).arg(url).output().expect("chromium");
    assert!(st.status.success() && png.is_file(), "no screenshot: {}", String::from_utf8_lossy(&st.stderr));
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(png).unwrap()));
    let mut r = dec.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size().unwrap()];
    let info = r.next_frame(&mut buf).unwrap();
    let ch = info.color_type.samples();
    assert!(ch >= 3, "{:?}", info.color_type);
    let px = buf[..info.buffer_size()].chunks(ch).map(|c| [c[0], c[1], c[2]]).collect();
    (info.width as usize, info.height as usize, px)
}

fn file_url(p: &Path) -> String {
    format!("file://{}", p.canonicalize().unwrap().display())
}

#[test]
fn the_page_in_headless_chromium_shows_the_reports_worst_self_pair_and_the_robot() {
    let dir = ur5_folder();
    let page = dir.join("preview.html");
    assert!(page.is_file(), "idexp excite writes preview.html");
    let (pair, dist, t) = report_worst_self(&dir);
    let url = format!("{}#t={t}", file_url(&page));
    let s = page_state(&url);
    assert_eq!(s["ready"], true, "{s}");
    let st = s["t"].as_f64().unwrap();
    assert!((st - t).abs() < 1e-9, "the page went to t = {st}, asked {t}");
    assert_eq!(s["self"]["pair"].as_str().unwrap(), pair, "{s}");
    let d = s["self"]["distance"].as_f64().unwrap();
    assert!((d - dist).abs() <= 1e-6, "page {d} m, report.json {dist} m");
    assert_eq!(s["q"].as_array().unwrap().len(), 6);
    assert_eq!(s["phase"].as_str().unwrap(), "period 1");
    // the witness points are `distance` apart (the drawn segment)
    let p: Vec<f64> = s["self"]["p1"]
        .as_array()
        .unwrap()
        .iter()
        .chain(s["self"]["p2"].as_array().unwrap())
        .map(|v| v.as_f64().unwrap())
        .collect();
    let len = ((p[0] - p[3]).powi(2) + (p[1] - p[4]).powi(2) + (p[2] - p[5]).powi(2)).sqrt();
    assert!((len - d).abs() < 1e-5, "segment {len} m, distance {d} m");

    // a screenshot at that instant: not blank, and the robot is in it
    let shots = root().join("target/preview-test");
    let (w, h, with) = screenshot(&url, &shots.join("preview_ur5.png"));
    let (w2, h2, without) = screenshot(&format!("{url}&hide=robot,skeleton,pairs,path"), &shots.join("preview_ur5_no_robot.png"));
    assert_eq!((w, h), (w2, h2));
    let lum: Vec<f64> = with.iter().map(|p| 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64).collect();
    let mean = lum.iter().sum::<f64>() / lum.len() as f64;
    let var = lum.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / lum.len() as f64;
    assert!(var > 100.0, "the screenshot is blank: luminance variance {var}");
    // the 3D view is the left 880 px: the robot changes a good part of it
    let view_w = w.saturating_sub(400);
    let mut changed = 0;
    for y in 0..h.saturating_sub(70) {
        for x in 0..view_w {
            let (a, b) = (with[y * w + x], without[y * w + x]);
            if a.iter().zip(b).any(|(u, v)| u.abs_diff(v) > 40) {
                changed += 1;
            }
        }
    }
    let frac = changed as f64 / (view_w * (h - 70)) as f64;
    assert!(
        frac > 0.01,
        "the robot is not visible: {:.4} % of the view changes when it is hidden",
        100.0 * frac
    );
}

#[test]
fn the_worst_instants_and_closest_pairs_are_the_exhaustive_minima() {
    let dir = ur5_folder();
    let design = idexp::excitation::design::ExciteDesign::load(&root().join("designs/excite_ur5.toml")).unwrap();
    let robot = idexp::robot::load(&design.robot).unwrap();
    let setup = Setup::from_design(&design, robot, "excite_ur5").unwrap();
    let motion = read_rows(&dir.join("trajectory.csv"), 6).unwrap();
    let pv = build(&setup, &motion, &PreviewOptions::default()).unwrap();
    let sc = setup.scene.as_ref().unwrap();
    let cap = sc.margin + 1.0;
    let Motion::Rows { t, q, .. } = &motion else { unreachable!() };
    // exhaustive: every pair's exact distance on every 10th row and on the
    // rows of the instants
    let mut kin = idexp::robot::kinematics::Kin::new(6);
    let mut poses = Vec::new();
    let rows_of_instants: Vec<usize> = pv.instants.iter().map(|i| t.iter().position(|&x| x == i.t).unwrap()).collect();
    let mut least = [f64::INFINITY; 2];
    for k in (0..t.len()).step_by(10).chain(rows_of_instants) {
        idexp::robot::kinematics::forward_kinematics(&setup.robot, &q[6 * k..6 * k + 6], &mut kin);
        sc.poses(&kin, &mut poses);
        for (i, p) in sc.pairs.iter().enumerate() {
            let c = usize::from(p.class == PairClass::World);
            least[c] = least[c].min(sc.pair_distance(i, &poses, cap));
        }
    }
    for (c, label) in ["closest self pair", "closest to the floor and cell"].iter().enumerate() {
        let ins = pv.instants.iter().find(|i| i.label == *label).unwrap();
        assert_eq!(ins.value, least[c], "{label}: the scan's minimum is the exhaustive one");
        let f = if c == 0 { &pv.closest_self } else { &pv.closest_world };
        assert_eq!(f[ins.frame].unwrap().proximity.distance, ins.value, "{label}: its frame shows it");
    }
    // every frame's closest pair is the least of its class over every pair
    for fr in (0..pv.t.len()).step_by(37) {
        idexp::robot::kinematics::forward_kinematics(&setup.robot, &pv.q[6 * fr..6 * fr + 6], &mut kin);
        sc.poses(&kin, &mut poses);
        for (c, got) in [&pv.closest_self, &pv.closest_world].iter().enumerate() {
            let class = if c == 0 { PairClass::SelfCollision } else { PairClass::World };
            let best = sc
                .pairs
                .iter()
                .enumerate()
                .filter(|(_, p)| p.class == class)
                .map(|(i, _)| sc.pair_distance(i, &poses, cap))
                .fold(f64::INFINITY, f64::min);
            assert_eq!(got[fr].map_or(cap, |x| x.proximity.distance), best, "frame {fr} class {c}");
        }
    }
    // the display frames: about 30 per second, and the last row
    let span = t[t.len() - 1] - t[0];
    assert!((pv.t.len() as f64 - 30.0 * span).abs() < 20.0, "{} frames for {span} s", pv.t.len());
    assert_eq!(pv.t[pv.t.len() - 1], t[t.len() - 1]);
    // the smallest position margin is the exhaustive one
    let ins = pv.instants.iter().find(|i| i.label == "smallest position margin").unwrap();
    let mut pm = f64::INFINITY;
    for k in 0..t.len() {
        for j in 0..6 {
            let [lo, hi] = setup.limits.position[j];
            pm = pm.min((q[6 * k + j] - lo).min(hi - q[6 * k + j]));
        }
    }
    assert_eq!(ins.value, pm);
}

#[test]
fn view_writes_the_page_for_a_folder_and_for_a_csv_and_refuses_bad_input() {
    let dir = ur5_folder();
    let out = root().join("target/preview-test/view_csv");
    let _ = std::fs::remove_dir_all(&out);
    let st = idexp()
        .args(["view", "--robot", "designs/robots/ur5.toml", "--trajectory"])
        .arg(dir.join("trajectory.csv"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
    let html = std::fs::read_to_string(out.join("preview.html")).unwrap();
    assert!(html.starts_with("<!doctype html>") && html.contains("three.js 0.184.0"));
    // the folder form writes the same page the excite run wrote
    let again = root().join("target/preview-test/view_folder");
    let st = idexp().arg("view").arg(&dir).arg("--out").arg(&again).output().unwrap();
    assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
    assert_eq!(
        std::fs::read(again.join("preview.html")).unwrap(),
        std::fs::read(dir.join("preview.html")).unwrap()
    );
    // bad input: exit 1 naming the file and the column; usage: exit 2
    let bad = root().join("target/preview-test/bad.csv");
    std::fs::write(&bad, "t,q1,q2,q3,q4,q5,q6\n0,0,0,0,0,0,0\n").unwrap();
    let st = idexp()
        .args(["view", "--robot", "designs/robots/ur5.toml", "--trajectory"])
        .arg(&bad)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&st.stderr);
    assert_eq!(st.status.code(), Some(1), "{err}");
    assert!(err.contains("bad.csv") && err.contains("qd"), "{err}");
    let st = idexp().args(["view", "no/such/folder"]).output().unwrap();
    assert_eq!(st.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&st.stderr).contains("no/such/folder"));
    let st = idexp().args(["view", "--robot", "designs/robots/ur5.toml"]).output().unwrap();
    assert_eq!(st.status.code(), Some(2));
}

/// report.json labels the clock of its worst instants: `result.margins[].at`
/// is on the period's clock, `worst_instants[].at_delivered_s` on the
/// delivered clock of trajectory.csv and the preview. Checked against
/// trajectory.csv itself: at every joint-state margin's delivered instant the
/// row (in period 1) holds the worst value reported; read on the period's
/// clock instead, the rows hold other values (the clocks differ by the lead-in).
#[test]
fn the_reports_worst_instants_are_labelled_and_found_in_trajectory_csv() {
    let dir = ur5_folder();
    let report = read_json(&dir.join("report.json"));
    assert!(report["margins_at_clock"].as_str().unwrap().contains("from the start of the period"));
    let margins = report["result"]["margins"].as_array().unwrap();
    let instants = report["worst_instants"].as_array().unwrap();
    assert_eq!(margins.len(), instants.len());
    let text = std::fs::read_to_string(dir.join("trajectory.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (tc, sc) = (col("t"), col("segment"));
    let row_at = |t: f64| rows.iter().find(|r| (r[tc] - t).abs() < 1e-9);
    let (mut checked, mut other_clock_differs) = (0, 0);
    for (m, w) in margins.iter().zip(instants) {
        assert_eq!(m["name"], w["name"]);
        assert_eq!(m["at"], w["at_period_s"]);
        if !matches!(m["kind"].as_str(), Some("position" | "velocity" | "acceleration")) {
            continue;
        }
        let c = col(m["name"].as_str().unwrap().split(' ').next().unwrap());
        let worst = m["worst"].as_f64().unwrap();
        let r = row_at(w["at_delivered_s"].as_f64().unwrap()).expect("a row at the delivered instant");
        assert_eq!(r[sc], 1.0, "{m}: period 1");
        assert!((r[c] - worst).abs() <= 1e-12 * worst.abs().max(1.0), "{m}: trajectory.csv has {}", r[c]);
        checked += 1;
        let p = row_at(w["at_period_s"].as_f64().unwrap()).unwrap();
        if (p[c] - worst).abs() > 1e-6 {
            other_clock_differs += 1;
        }
    }
    assert_eq!(checked, 36, "q, qd, qdd upper and lower for six joints");
    assert!(other_clock_differs > 30, "{other_clock_differs} of 36");
    // report.txt says which clock each instant is on
    let txt = std::fs::read_to_string(dir.join("report.txt")).unwrap();
    let line = txt.lines().find(|l| l.contains("worst self distance")).unwrap();
    assert!(
        line.contains("into the period (t = ") && line.contains("on the delivered clock of trajectory.csv and the preview"),
        "{line}"
    );
}
