//! `camgeom monitor` (#39) on streams made here with the board's own framing
//! (`camgeom_fw_app::link`, `camgeom_fw_app::report`): every frame record comes out as one JSON
//! line with the record's numbers; a damaged frame is counted and skipped, the rest still
//! decode; a missing file is an input error. The emulated board's real stream is checked by
//! the main job (`cargo xtask run`, the tag job).

use camgeom::target::TargetState;
use camgeom_fw_app::link::{encode_frame, max_frame_len};
use camgeom_fw_app::report::{FrameRecord, PoseRecord, RECORD_LEN, SummaryRecord};
use serde_json::Value;

use crate::common::{camgeom, scratch_file};

fn frame(index: u32) -> FrameRecord {
    let pose = PoseRecord {
        t: [0.01 * index as f32, -0.02, 0.5],
        r: [0.1, 0.2, 0.3 + index as f32],
        rms_px: 0.25,
    };
    FrameRecord {
        index,
        state: TargetState::Tracking,
        tracked: 20 + index as u16,
        inliers: 18,
        pose: index.is_multiple_of(2).then_some((pose, pose)),
        ..FrameRecord::default()
    }
}

/// The stream of frames 0..n and a summary, each record framed in order.
fn stream(n: u32) -> Vec<u8> {
    let mut out = Vec::new();
    let mut buf = [0u8; max_frame_len(RECORD_LEN)];
    let summary = SummaryRecord {
        frames: n,
        tracking: n,
        ..SummaryRecord::default()
    };
    let records = (0..n).map(|k| frame(k).encode()).chain([summary.encode()]);
    for (seq, rec) in records.enumerate() {
        let m = encode_frame(seq as u16, &rec, &mut buf).unwrap();
        out.extend_from_slice(&buf[..m]);
    }
    out
}

fn lines(bytes: &[u8]) -> Vec<Value> {
    let path = scratch_file("stream", "").with_extension("bin");
    std::fs::write(&path, bytes).unwrap();
    let out = camgeom(&["monitor", "--json", "--replay", path.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn every_frame_record_is_one_json_line_and_damage_is_counted() {
    let clean = stream(12);
    let got = lines(&clean);
    assert_eq!(got.len(), 12 + 2);
    for (k, v) in got[..12].iter().enumerate() {
        let f = frame(k as u32);
        assert_eq!(v["frame"], k as u64);
        assert_eq!(v["state"], "tracking");
        assert_eq!(v["tracked"], u64::from(f.tracked));
        match f.pose {
            Some((p, _)) => {
                let t: Vec<f32> = v["pose"]["t"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|x| x.as_f64().unwrap() as f32)
                    .collect();
                assert_eq!(t, p.t);
            }
            None => assert!(v["pose"].is_null()),
        }
    }
    assert_eq!(got[12]["summary"]["frames"], 12);
    assert_eq!(got[13]["link"]["frames"], 13);
    assert_eq!(got[13]["link"]["damaged"], 0);
    // One byte flipped in the middle of the stream: one frame damaged and lost, no other.
    let mut bad = clean.clone();
    let mid = bad.len() / 2;
    bad[mid] ^= 0x10;
    let got = lines(&bad);
    let link = &got.last().unwrap()["link"];
    assert_eq!(link["frames"], 12, "{link}");
    assert_eq!(link["damaged"], 1, "{link}");
    assert_eq!(link["lost"], 1, "{link}");
    assert_eq!(got.len(), 11 + 2);
}

#[test]
fn a_missing_stream_is_an_input_error() {
    let out = camgeom(&["monitor", "--replay", "no/such/stream.bin"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("stream.bin"));
}
