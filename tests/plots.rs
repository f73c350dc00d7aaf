//! The SVG figures are readable: every tick label is formatted (no
//! 17-digit rounding artefacts, no "-0"), log axes carry decade ticks, and
//! no text is placed outside the canvas. Checked on the figures written by
//! shipped designs (excite, positions, multisine/frf/fit) and on the tick
//! functions themselves.
#![cfg(feature = "cli")]

mod common;
use common::root;
use idexp::io::plot::{linear_range, log_ticks, tick_label};
use std::path::Path;
use std::process::Command;

#[test]
fn tick_labels_are_short_and_log_ticks_are_decades_with_subdivisions() {
    assert_eq!(tick_label(9.999999999999999e-5), "1e-4");
    assert_eq!(tick_label(-0.0), "0");
    assert_eq!(tick_label(1e-17), "0");
    assert_eq!(tick_label(0.25), "0.25");
    assert_eq!(tick_label(40.0), "40");
    assert_eq!(tick_label(2.5e6), "2.5e6");
    assert_eq!(tick_label(0.30000000000000004), "0.3");
    assert_eq!(log_ticks(3.0, 150.0), vec![5.0, 10.0, 20.0, 50.0, 100.0]);
    assert_eq!(log_ticks(1e-6, 1.0), vec![1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0]);
    assert_eq!(log_ticks(40.0, 100.0), vec![40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0]);
    assert!(log_ticks(1e-30, 1e30).len() <= 9);
}

/// A `<text>` element: x, y and content.
type Text = (f64, f64, String);

/// (width, height) of the SVG and every <text> with its x, y and content.
fn texts(svg: &str) -> ((f64, f64), Vec<Text>) {
    let attr = |tag: &str, name: &str| -> Option<f64> {
        let i = tag.find(&format!(" {name}=\""))? + name.len() + 3;
        tag[i..].split('"').next()?.parse().ok()
    };
    let head = &svg[svg.find("<svg").unwrap()..];
    let head = &head[..head.find('>').unwrap()];
    let size = (attr(head, "width").unwrap(), attr(head, "height").unwrap());
    let mut out = Vec::new();
    let mut rest = svg;
    while let Some(i) = rest.find("<text") {
        let tag_end = rest[i..].find('>').unwrap() + i;
        let tag = &rest[i..tag_end];
        let close = rest[tag_end..].find("</text>").unwrap() + tag_end;
        let body = rest[tag_end + 1..close].trim().to_string();
        if let (Some(x), Some(y)) = (attr(tag, "x"), attr(tag, "y")) {
            out.push((x, y, body));
        }
        rest = &rest[close..];
    }
    (size, out)
}

/// A number with 12 or more significant digits (a rounding artefact).
fn long_number(t: &str) -> bool {
    let digits: String = t
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.' || *c == '-')
        .filter(|c| c.is_ascii_digit())
        .collect();
    digits.trim_start_matches('0').len() >= 12
}

fn check_svg(path: &Path) {
    let svg = std::fs::read_to_string(path).unwrap();
    let ((w, h), ts) = texts(&svg);
    assert!(!ts.is_empty(), "{}: no text", path.display());
    for (x, y, t) in &ts {
        assert!(!long_number(t), "{}: tick label `{t}`", path.display());
        assert!(t != "-0" && t != "-0.0", "{}: tick label `{t}`", path.display());
        assert!(
            (-1.0..=w + 1.0).contains(x) && (-1.0..=h + 1.0).contains(y),
            "{}: `{t}` at ({x}, {y}) outside {w}×{h}",
            path.display()
        );
    }
}

fn run(args: &[&str]) {
    let o = Command::new(env!("CARGO_BIN_EXE_idexp"))
        .current_dir(root(""))
        .env("IDEXP_NO_PROGRESS", "1")
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.code().is_some_and(|c| c == 0 || c == 3),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

fn svgs(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "svg"))
        .collect();
    v.sort();
    v
}

#[test]
fn figures_of_shipped_designs_have_formatted_ticks_inside_the_canvas() {
    let tmp = tempfile::tempdir().unwrap();
    let t = |s: &str| tmp.path().join(s).to_str().unwrap().to_string();
    run(&["excite", "designs/excite_ur5.toml", "--out", &t("ex")]);
    run(&["positions", "designs/positions_file_a.toml", "--out", &t("pa")]);
    run(&["positions", "designs/positions_elastic6_small.toml", "--out", &t("pe")]);
    run(&["frf", "designs/elastic_industrial6.toml", "--out", &t("el")]);
    run(&["fit", "designs/elastic_industrial6.toml", "--starts", "3", "--out", &t("el")]);
    let mut n = 0;
    for d in ["ex", "pa", "pe", "el/frf", "el/fit_lls_user"] {
        for p in svgs(&tmp.path().join(d)) {
            check_svg(&p);
            n += 1;
        }
    }
    assert!(n >= 10, "{n} figures");
    // the Bode plots: decade ticks on the frequency axis, none colliding
    let bode = std::fs::read_to_string(tmp.path().join("el/fit_lls_user/bode_pos1.svg")).unwrap();
    let labels: Vec<String> = texts(&bode).1.into_iter().map(|t| t.2).collect();
    for want in ["10", "100", "5", "50"] {
        assert!(labels.iter().any(|l| l == want), "no tick `{want}` in {labels:?}");
    }
    // |G| with the unit of the acceleration output of that design, on every panel
    let units = labels.iter().filter(|l| l.starts_with("|G") && l.ends_with("((rad/s²)/(N·m))")).count();
    assert_eq!(units, 36, "{labels:?}");
    let frf = std::fs::read_to_string(tmp.path().join("el/frf/frf.svg")).unwrap();
    assert!(texts(&frf).1.iter().any(|t| t.2.ends_with("((rad/s²)/(N·m))")));
    // the positions top view of a planar arm (y ≡ 0 up to rounding): a
    // symmetric range, not a row of "0" ticks
    let poses = std::fs::read_to_string(tmp.path().join("pa/poses.svg")).unwrap();
    let labels: Vec<String> = texts(&poses).1.into_iter().map(|t| t.2).collect();
    assert!(labels.iter().any(|l| l == "-0.5") && labels.iter().any(|l| l == "0.5"), "{labels:?}");
}

#[test]
fn noise_spans_get_a_symmetric_range() {
    assert_eq!(linear_range(-1e-16, 2e-17), (-0.5, 0.5));
    assert_eq!(linear_range(3.0, 3.0), (1.5, 4.5));
    let (lo, hi) = linear_range(0.0, 10.0);
    assert!((lo + 0.5).abs() < 1e-12 && (hi - 10.5).abs() < 1e-12);
}

fn labels_of(path: &Path) -> Vec<String> {
    check_svg(path);
    texts(&std::fs::read_to_string(path).unwrap()).1.into_iter().map(|t| t.2).collect()
}

#[test]
fn identification_figures_name_parameters_e_tol_and_both_gravity_branches() {
    let tmp = tempfile::tempdir().unwrap();
    let t = |s: &str| tmp.path().join(s).to_str().unwrap().to_string();
    run(&["simulate", "designs/sim_rpr_pick_place.toml", "--out", &t("sp")]);
    run(&["simulate", "designs/sim_rpr_pick_place_validate.toml", "--out", &t("spv")]);
    run(&[
        "identify",
        "tests/data/ident/rpr_drives.toml",
        &t("sp"),
        "--validate",
        &t("spv"),
        "--reduce",
        "--out",
        &t("ip"),
    ]);
    run(&["simulate", "designs/sim_puma_gravity.toml", "--out", &t("sg")]);
    run(&[
        "identify",
        "designs/robots/puma560.toml",
        &t("sg"),
        "--experiment",
        "gravity",
        "--joint",
        "2",
        "--out",
        &t("pg"),
    ]);
    let est: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(tmp.path().join("ip/estimate.json")).unwrap()).unwrap();
    let names: Vec<String> = est["names"].as_array().unwrap().iter().map(|v| v.as_str().unwrap().to_string()).collect();
    assert!(names.len() >= 5, "{names:?}");
    // params.svg: the study folder of the one-run form has none any more; the
    // figure's panels are still the library's (ident::output::params_panels),
    // drawn here from the same design (the folder's study.json) as the old
    // one-run writer drew them
    let design: idexp::ident::study::StudyDesign = serde_json::from_str(&std::fs::read_to_string(tmp.path().join("ip/study.json")).unwrap()).unwrap();
    let res = idexp::ident::study::run_study(&design, &root(""), &idexp::optim::Control::new()).unwrap();
    assert_eq!(res.estimate.names, names);
    let params_svg = tmp.path().join("ip_params.svg");
    idexp::io::plot::write_svg(
        &params_svg,
        "identified base parameters",
        &idexp::ident::output::params_panels(&res.estimate),
        1,
    )
    .unwrap();
    // params.svg: every name under each of its two panels, σ error bars in the legend
    let params = labels_of(&params_svg);
    for n in &names {
        assert!(params.iter().filter(|l| *l == n).count() >= 2, "`{n}` not on the x axes: {params:?}");
    }
    assert!(params.iter().any(|l| l.contains('σ')), "{params:?}");
    // reduction.svg: the tried parameters and the e_tol line in the legend
    let red = labels_of(&tmp.path().join("ip/reduction.svg"));
    assert!(red.iter().any(|l| l.starts_with("e_tol = ")), "{red:?}");
    let csv = std::fs::read_to_string(tmp.path().join("ip/reduction.csv")).unwrap();
    for row in csv.lines().skip(1) {
        let p = row.split(',').nth(1).unwrap();
        assert!(red.iter().any(|l| l == p), "`{p}` not in {red:?}");
    }
    // gravity.svg: both fitted branches k sin(q + q_off) + c±
    let grav = labels_of(&tmp.path().join("pg/gravity.svg"));
    assert!(grav.iter().any(|l| l.contains("+ c₊")), "{grav:?}");
    assert!(grav.iter().any(|l| l.contains("+ c₋")), "{grav:?}");
    // the legend covers no measured point (its box: the translucent white rect)
    let svg = std::fs::read_to_string(tmp.path().join("pg/gravity.svg")).unwrap();
    let boxes: Vec<[f64; 4]> = elements(&svg, "rect")
        .into_iter()
        .filter(|t| t.contains("opacity=\"0.8\"") && t.contains("fill=\"#FFFFFF\""))
        .map(|t| [num(&t, "x"), num(&t, "y"), num(&t, "width"), num(&t, "height")])
        .collect();
    assert_eq!(boxes.len(), 1, "one legend");
    let [bx, by, bw, bh] = boxes[0];
    // the data points (r = 2; the legend's dot glyph has r = 3)
    let circles: Vec<_> = elements(&svg, "circle").into_iter().filter(|c| num(c, "r") == 2.0).collect();
    assert!(circles.len() > 1000, "{} points", circles.len());
    for c in &circles {
        let (cx, cy) = (num(c, "cx"), num(c, "cy"));
        assert!(
            !(bx..=bx + bw).contains(&cx) || !(by..=by + bh).contains(&cy),
            "point ({cx}, {cy}) under the legend {:?}",
            boxes[0]
        );
    }
    // params.svg: each parameter name starts under the bars of its panel,
    // never inside the plot (rotated labels used to be centred on the axis)
    let svg = std::fs::read_to_string(&params_svg).unwrap();
    let bars: Vec<[f64; 4]> = elements(&svg, "rect")
        .into_iter()
        .filter(|t| t.contains("fill=\"#1F77B4\""))
        .map(|t| [num(&t, "x"), num(&t, "y"), num(&t, "width"), num(&t, "height")])
        .collect();
    assert!(bars.len() >= 2 * names.len(), "{} bars", bars.len());
    assert!(bars.iter().all(|b| b[2] >= 5.0), "bars are at least 5 px wide: {bars:?}");
    let (_, ts) = texts(&svg);
    // drawn from their start point (a centred rotated label reaches half its
    // length above the anchor, into the plot)
    let starts = elements(&svg, "text")
        .into_iter()
        .filter(|t| t.contains("rotate(90") && t.contains("text-anchor=\"start\""))
        .count();
    assert!(starts >= 2 * names.len(), "{starts} rotated names drawn from their start");
    for (x, y, t) in ts.iter().filter(|t| names.contains(&t.2)) {
        for b in bars.iter().filter(|b| (b[0]..=b[0] + b[2]).contains(x) && b[1] < *y && b[1] > y - 300.0) {
            assert!(b[1] + b[3] <= *y, "`{t}` at y {y} starts inside its bar {b:?}");
        }
    }
}

/// Every `<name ...>` opening tag of the SVG.
fn elements(svg: &str, name: &str) -> Vec<String> {
    let open = format!("<{name} ");
    let mut out = Vec::new();
    let mut rest = svg;
    while let Some(i) = rest.find(&open) {
        let end = rest[i..].find('>').unwrap() + i;
        out.push(rest[i..end].to_string());
        rest = &rest[end..];
    }
    out
}

/// A numeric attribute of a tag.
fn num(tag: &str, name: &str) -> f64 {
    let i = tag.find(&format!(" {name}=\"")).unwrap_or_else(|| panic!("no {name} in {tag}")) + name.len() + 3;
    tag[i..].split('"').next().unwrap().parse().unwrap()
}

#[test]
fn legend_growth_line_breaks_and_shortened_titles() {
    use idexp::io::plot::{fit_text, legend_place, line_segments};
    // data filling every corner of the unit square: the range grows until
    // the chosen corner's box (30 % × 30 %) is empty
    let fill: Vec<(f64, f64)> = (0..=20).flat_map(|i| (0..=20).map(move |j| (i as f64 / 20.0, j as f64 / 20.0))).collect();
    let (k, (lo, hi)) = legend_place(fill.iter().copied(), (0.0, 1.0, false), (0.0, 1.0, false), (0.3, 0.3));
    assert!(hi > 1.0 || lo < 0.0, "range not grown: {lo} {hi}");
    let inside = fill.iter().filter(|(x, y)| {
        let (u, w) = (*x, (y - lo) / (hi - lo));
        let col = if k % 2 == 0 { u <= 0.3 } else { u >= 0.7 };
        let row = if k < 2 { w >= 0.7 } else { w <= 0.3 };
        col && row
    });
    assert_eq!(inside.count(), 0, "corner {k}, range {lo}..{hi}");
    // an empty corner keeps the range
    let low: Vec<(f64, f64)> = (0..=20).map(|i| (i as f64 / 20.0, 0.1)).collect();
    assert_eq!(
        legend_place(low.iter().copied(), (0.0, 1.0, false), (0.0, 1.0, false), (0.3, 0.3)),
        (0, (0.0, 1.0))
    );
    // a time series with rows left out is drawn in pieces
    let t: Vec<(f64, f64)> = (0..10).chain(50..60).map(|i| (i as f64, 0.0)).collect();
    let segs = line_segments(&t);
    assert_eq!(segs.iter().map(Vec::len).collect::<Vec<_>>(), vec![10, 10]);
    // a closed path (x not increasing) stays one line
    let path: Vec<(f64, f64)> = (0..20).map(|i| ((i as f64).cos(), (i as f64).sin())).collect();
    assert_eq!(line_segments(&path).len(), 1);
    assert_eq!(fit_text("short", 10), "short");
    let long = fit_text("identifiability of /a/very/long/folder/name/excite_ur5/trajectory.csv", 40);
    assert_eq!(long.chars().count(), 40);
    assert!(
        long.ends_with("trajectory.csv") && long.starts_with("identifiability") && long.contains('…'),
        "{long}"
    );
}

#[test]
fn legends_go_to_the_corner_with_the_fewest_points() {
    use idexp::io::plot::emptiest_corner;
    // a rising line fills the lower-left and upper-right corners
    let rising: Vec<(f64, f64)> = (0..=100).map(|i| (i as f64, i as f64)).collect();
    let c = emptiest_corner(rising.iter().copied(), (0.0, 100.0, false), (0.0, 100.0, false));
    assert!(c == 0 || c == 3, "{c}");
    // a decaying singular-value spectrum on a log axis: the upper right is empty
    let decay: Vec<(f64, f64)> = (1..=40).map(|i| (i as f64, 10f64.powf(-(i as f64) / 5.0))).collect();
    assert_eq!(emptiest_corner(decay.iter().copied(), (1.0, 40.0, false), (1e-8, 1.0, true)), 1);
    // data high everywhere: a lower corner
    let high: Vec<(f64, f64)> = (0..=100).map(|i| (i as f64, 90.0 + (i % 7) as f64)).collect();
    assert!(emptiest_corner(high.iter().copied(), (0.0, 100.0, false), (0.0, 100.0, false)) >= 2);
}
