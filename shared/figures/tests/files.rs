//! Every figure is written as a valid SVG and PNG of the stated size, with its text.

use dkrrt_figures::{
    grouped_bars, path_projections, percentile_curves, time_panels, Bar, BarPanel, Curve, CurvePanel, HLine,
    Series, TimePanel,
};

fn png_size(b: &[u8]) -> (u32, u32) {
    assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&b[12..16], b"IHDR");
    (u32::from_be_bytes(b[16..20].try_into().unwrap()), u32::from_be_bytes(b[20..24].try_into().unwrap()))
}

fn check(paths: &[std::path::PathBuf; 2], size: (u32, u32), text: &str) {
    let svg = std::fs::read_to_string(&paths[0]).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"), "{}", &svg[..80.min(svg.len())]);
    assert!(svg.contains(text), "the SVG carries its text ({text})");
    let png = std::fs::read(&paths[1]).unwrap();
    assert_eq!(png_size(&png), size);
    // Not a blank canvas: a blank white PNG of this size compresses to a few hundred bytes.
    assert!(png.len() > 10_000, "{} bytes", png.len());
}

#[test]
fn bars_series_and_paths_render_to_svg_and_png() {
    let d = std::env::temp_dir().join(format!("dkrrt-figures-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let bars: Vec<Bar> = ["dense", "fast-crossing"]
        .iter()
        .flat_map(|g| {
            ["rrt-static", "dk-rrt"].iter().enumerate().map(move |(i, m)| Bar {
                group: g.to_string(),
                series: m.to_string(),
                value: 40.0 + 50.0 * i as f64,
                interval: Some((30.0 + 50.0 * i as f64, 50.0 + 45.0 * i as f64)),
            })
        })
        .collect();
    let panel =
        BarPanel { title: "completion".into(), y_label: "%".into(), bars, y_range: Some((0.0, 100.0)) };
    let p = grouped_bars(&d.join("bars"), "Bars test", &[panel.clone(), panel]).unwrap();
    check(&p, (1100, 660), "Bars test");

    let sine: Vec<(f64, f64)> = (0..500).map(|i| (i as f64 * 0.02, (i as f64 * 0.02).sin())).collect();
    let panel = TimePanel {
        title: "velocity".into(),
        y_label: "fraction of limit".into(),
        series: vec![Series { name: "joint 1".into(), points: sine, color: 0, dashed: true }],
        lines: vec![HLine { y: 1.0, name: "limit".into() }],
    };
    let p = time_panels(&d.join("series"), "Series test", &[panel]).unwrap();
    check(&p, (1100, 320), "Series test");

    let helix: Vec<[f64; 3]> =
        (0..300).map(|i| [(i as f64 * 0.05).cos(), (i as f64 * 0.05).sin(), i as f64 * 0.003]).collect();
    let shifted: Vec<[f64; 3]> = helix.iter().map(|p| [p[0] + 0.01, p[1], p[2]]).collect();
    let debris = vec![(0..100).map(|i| [-2.0 + 0.04 * i as f64, 0.3, 0.5]).collect::<Vec<_>>()];
    let p = path_projections(&d.join("paths"), "Paths test", &helix, &shifted, &debris).unwrap();
    check(&p, (1500, 560), "x–y projection");

    let curve =
        |scale: f64| (0..40).map(|i| (i as f64 * 0.1, scale * (1.0 + (i as f64 * 0.1).exp()))).collect();
    let panel = CurvePanel {
        title: "wake-up latency".into(),
        y_label: "us".into(),
        curves: vec![
            Curve { name: "baseline".into(), points: curve(1.0), color: 7, dashed: true },
            Curve { name: "tracker".into(), points: curve(1.2), color: 0, dashed: false },
        ],
    };
    let p =
        percentile_curves(&d.join("curves"), "Curves test", &[panel.clone(), panel.clone(), panel]).unwrap();
    check(&p, (1120, 820), "99.9%");
    let _ = std::fs::remove_dir_all(d);
}

#[test]
fn an_unwritable_place_is_an_error_not_a_panic() {
    let e = grouped_bars(std::path::Path::new("/dev/null/x"), "t", &[]).unwrap_err();
    assert!(!e.is_empty());
}
