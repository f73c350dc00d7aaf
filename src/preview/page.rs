//! The HTML page: the template, the page's script, three.js (the npm
//! package `three`, pinned, minified module build, in `assets/three/` with
//! its licence) and the data, all in one file.
//!
//! Large arrays travel as base64 of little-endian typed arrays (f64 for
//! times, joint values and distances, f32 for poses and witness points, i32
//! for indices); the rest as JSON.

use super::{geometry, Closest, Preview, Setup};
use crate::error::{Error, Result};
use base64::Engine as _;
use serde_json::json;

/// The three.js version embedded (assets/three/, from the npm registry).
pub const THREE_VERSION: &str = "0.184.0";
const THREE_CORE: &str = include_str!("../../assets/three/three.core.min.js");
const THREE_MODULE: &str = include_str!("../../assets/three/three.module.min.js");
const ORBIT_CONTROLS: &str = include_str!("../../assets/three/OrbitControls.js");
const THREE_LICENSE: &str = include_str!("../../assets/three/LICENSE");
const TEMPLATE: &str = include_str!("page.html");
const SCRIPT: &str = include_str!("page.js");

fn b64<T: Copy, const W: usize>(v: &[T], bytes: impl Fn(T) -> [u8; W]) -> String {
    let mut raw = Vec::with_capacity(v.len() * W);
    for x in v {
        raw.extend(bytes(*x));
    }
    base64::engine::general_purpose::STANDARD.encode(raw)
}

fn f64s(v: &[f64]) -> String {
    b64(v, f64::to_le_bytes)
}

fn f32s(v: &[f32]) -> String {
    b64(v, f32::to_le_bytes)
}

fn i32s(v: &[i32]) -> String {
    b64(v, i32::to_le_bytes)
}

fn finite_or_null(v: f64) -> serde_json::Value {
    if v.is_finite() {
        json!(v)
    } else {
        serde_json::Value::Null
    }
}

/// The closest pairs of one class: pair index (−1: none within the cap),
/// distance, witness points p1 then p2.
fn closest_json(c: &[Option<Closest>]) -> serde_json::Value {
    let pair: Vec<i32> = c.iter().map(|x| x.map_or(-1, |x| x.pair as i32)).collect();
    let dist: Vec<f64> = c.iter().map(|x| x.map_or(f64::NAN, |x| x.proximity.distance)).collect();
    let mut w: Vec<f32> = Vec::with_capacity(6 * c.len());
    for x in c {
        match x {
            Some(x) => {
                let (a, b) = (x.proximity.p1, x.proximity.p2);
                w.extend([a.x, a.y, a.z, b.x, b.y, b.z].map(|v| v as f32));
            }
            None => w.extend([0.0; 6]),
        }
    }
    json!({ "pair": i32s(&pair), "distance": f64s(&dist), "witness": f32s(&w) })
}

/// The page's data (JSON).
fn data(setup: &Setup, pv: &Preview) -> serde_json::Value {
    let robot = &setup.robot;
    let mut bodies = Vec::new();
    let mut planes = Vec::new();
    let mut pairs = Vec::new();
    let (margin, excluded) = match &setup.scene {
        Some(sc) => {
            for (i, b) in sc.bodies().iter().enumerate() {
                let (meshes, pl) = geometry::body_meshes(b);
                let parts: Vec<_> = meshes
                    .iter()
                    .map(|m| json!({ "vertices": f32s(&m.vertices), "triangles": i32s(&m.triangles.iter().map(|&v| v as i32).collect::<Vec<_>>()), "pad": m.pad }))
                    .collect();
                let link = sc.owner(i);
                // robot bodies first (base, then one per link), then the obstacles
                let obstacle = i > robot.dof();
                bodies.push(json!({ "name": b.name, "link": link, "obstacle": obstacle, "parts": parts }));
                for p in pl {
                    planes.push(json!({ "name": b.name, "normal": p.normal, "offset": p.offset }));
                }
            }
            for (k, p) in sc.pairs.iter().enumerate() {
                let (a, b) = sc.pair_bodies(k);
                pairs.push(json!({ "label": p.label(), "a": p.a, "b": p.b, "class": p.class.label(), "bodies": [a, b] }));
            }
            (Some(sc.margin), sc.excluded.len())
        }
        None => (None, 0),
    };
    let joints: Vec<_> = robot
        .joints
        .iter()
        .enumerate()
        .map(|(j, jt)| {
            let revolute = jt.kind == crate::robot::JointKind::Revolute;
            json!({
                "name": jt.name,
                "parent": jt.parent,
                "revolute": revolute,
                "unit": if revolute { "rad" } else { "m" },
                "position": [finite_or_null(setup.limits.position[j][0]), finite_or_null(setup.limits.position[j][1])],
                "velocity": finite_or_null(setup.limits.velocity[j]),
                "hard": [finite_or_null(jt.limits.lower), finite_or_null(jt.limits.upper)],
                "hard_velocity": finite_or_null(jt.limits.velocity),
            })
        })
        .collect();
    let segments: Vec<_> = pv
        .segments
        .iter()
        .map(|&(t0, t1, s)| json!({ "t0": t0, "t1": t1, "segment": s, "name": crate::excitation::execution::segment_name(s) }))
        .collect();
    let seg: Vec<i32> = pv.segment.iter().map(|&s| if s == i64::MIN { i32::MIN } else { s as i32 }).collect();
    json!({
        "title": setup.title,
        "robot": robot.name,
        "idexp_version": env!("CARGO_PKG_VERSION"),
        "three_version": THREE_VERSION,
        "dof": robot.dof(),
        "joints": joints,
        "limits_source": setup.limits_source,
        "bodies": bodies,
        "planes": planes,
        "pairs": pairs,
        "excluded_pairs": excluded,
        "margin": margin,
        "cap": pv.cap,
        "workspace": setup.workspace,
        "end_effector": robot.end_effector().name,
        "segments": segments,
        "rows": pv.rows,
        "instants": pv.instants,
        "report": setup.report,
        "frames": {
            "n": pv.t.len(),
            "t": f64s(&pv.t),
            "segment": i32s(&seg),
            "q": f64s(&pv.q),
            "qd": f64s(&pv.qd),
            "links": f32s(&pv.link_poses),
            "ee": f32s(&pv.ee),
            "self": closest_json(&pv.closest_self),
            "world": closest_json(&pv.closest_world),
        },
    })
}

/// Text that may sit inside a `<script>` element: no `</script`, no `<!--`.
fn script_safe(what: &str, s: &str) -> Result<()> {
    let lower = s.to_ascii_lowercase();
    if lower.contains("</script") || lower.contains("<!--") {
        return Err(Error::invalid(
            "preview.html",
            what,
            "contains `</script` or `<!--`: cannot be embedded in the page",
        ));
    }
    Ok(())
}

/// The whole page.
pub fn html(setup: &Setup, pv: &Preview) -> Result<String> {
    let data = serde_json::to_string(&data(setup, pv)).map_err(|e| Error::invalid("preview.html", "data", e.to_string()))?;
    // JSON escapes `<` nowhere by itself: names come from user files
    let data = data.replace('<', "\\u003c");
    for (what, s) in [
        ("three.core.min.js", THREE_CORE),
        ("three.module.min.js", THREE_MODULE),
        ("OrbitControls.js", ORBIT_CONTROLS),
        ("page.js", SCRIPT),
    ] {
        script_safe(what, s)?;
    }
    let title = setup.title.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;");
    let license = THREE_LICENSE
        .replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace("--", "- -");
    let mut out = String::with_capacity(data.len() + THREE_CORE.len() + THREE_MODULE.len() + ORBIT_CONTROLS.len() + 64 * 1024);
    let mut rest = TEMPLATE;
    // the template's placeholders, in order of appearance
    for (key, value) in [
        ("{{TITLE}}", title.as_str()),
        ("{{THREE_VERSION}}", THREE_VERSION),
        ("{{THREE_LICENSE}}", license.as_str()),
        ("{{THREE_CORE}}", THREE_CORE),
        ("{{THREE_MODULE}}", THREE_MODULE),
        ("{{ORBIT_CONTROLS}}", ORBIT_CONTROLS),
        ("{{DATA}}", data.as_str()),
        ("{{SCRIPT}}", SCRIPT),
    ] {
        let at = rest
            .find(key)
            .ok_or_else(|| Error::invalid("preview template", key, "placeholder missing or out of order"))?;
        out.push_str(&rest[..at]);
        out.push_str(value);
        rest = &rest[at + key.len()..];
    }
    out.push_str(rest);
    Ok(out)
}
