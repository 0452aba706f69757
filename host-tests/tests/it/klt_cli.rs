//! `camgeom flow` and `camgeom track` on the bundled data.

use crate::common::camgeom;
use camgeom_host::data_dir;

#[test]
fn flow_matches_opencv_on_the_basketball_pair() {
    let d = data_dir();
    let dir = std::env::temp_dir().join(format!("camgeom-klt-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let pts = dir.join("pts.csv");
    let fx = std::fs::read_to_string(d.join("fixtures/klt/basketball_real_lk.csv")).unwrap();
    let rows: Vec<Vec<f64>> = fx
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let mut csv = String::from("x,y\n");
    for r in &rows {
        csv.push_str(&format!("{},{}\n", r[0], r[1]));
    }
    std::fs::write(&pts, csv).unwrap();
    let a = d.join("middlebury/basketball1.png");
    let b = d.join("middlebury/basketball2.png");
    for extra in [&[][..], &["--fixed"][..]] {
        let mut args = vec![
            "flow",
            "--from",
            a.to_str().unwrap(),
            "--to",
            b.to_str().unwrap(),
            "--points",
            pts.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let out = camgeom(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8(out.stdout).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("x,y,status"));
        let mut n = 0;
        for (line, r) in lines.zip(&rows) {
            let f: Vec<&str> = line.split(',').collect();
            assert_eq!(f.len(), 3);
            assert_eq!(f[2] == "ok", r[4] > 0.5, "{line}");
            if f[2] == "ok" {
                let (x, y): (f64, f64) = (f[0].parse().unwrap(), f[1].parse().unwrap());
                assert!((x - r[2]).hypot(y - r[3]) < 0.01, "{line} vs {r:?}");
            } else {
                assert!(f[0] == "nan" && f[1] == "nan");
            }
            n += 1;
        }
        assert_eq!(n, rows.len());
    }
    // Input errors: exit status 2, one line on stderr, nothing on stdout.
    let out = camgeom(&[
        "flow",
        "--from",
        "nope.png",
        "--to",
        "nope.png",
        "--points",
        pts.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(out.stdout.is_empty());
    assert_eq!(String::from_utf8_lossy(&out.stderr).lines().count(), 1);
    let out = camgeom(&[
        "flow",
        "--from",
        a.to_str().unwrap(),
        "--to",
        b.to_str().unwrap(),
        "--points",
        pts.to_str().unwrap(),
        "--win",
        "2",
    ]);
    assert_eq!(out.status.code(), Some(2));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn track_writes_rows_and_overlays() {
    let d = data_dir();
    let dir = std::env::temp_dir().join(format!("camgeom-klt-track-{}", std::process::id()));
    let frames = dir.join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    for k in 0..5 {
        let name = format!("{k:04}.png");
        std::fs::copy(d.join("sequences/tree").join(&name), frames.join(&name)).unwrap();
    }
    let out_csv = dir.join("tracks.csv");
    let ov = dir.join("overlay");
    let out = camgeom(&[
        "track",
        "--frames",
        frames.to_str().unwrap(),
        "--out",
        out_csv.to_str().unwrap(),
        "--overlay",
        ov.to_str().unwrap(),
        "--max-tracks",
        "100",
        "--fixed",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["frames"], 5);
    let text = std::fs::read_to_string(&out_csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("frame,id,x,y"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    for k in 0..5 {
        let n = rows.iter().filter(|r| r[0] == k as f64).count();
        assert!(n > 50 && n <= 100, "frame {k}: {n}");
    }
    assert_eq!(std::fs::read_dir(&ov).unwrap().count(), 5);
    std::fs::remove_dir_all(&dir).ok();
}
