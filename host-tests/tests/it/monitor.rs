//! `camgeom monitor` (#39) on streams made here with the board's own framing
//! (`camgeom_fw_app::link`, `camgeom_fw_app::report`): every frame record comes out as one JSON
//! line with the record's numbers; a damaged frame is counted and skipped, the rest still
//! decode; a missing file is an input error. The emulated board's real stream is checked by
//! the main job (`cargo xtask run`, the tag job).
//!
//! Commands: `--commands-out` writes frames the board's receiver (`Deframer`,
//! `Command::decode`) reads back as the commands asked for, the camera's values as the camera
//! file has them (read here with `serde_json`, not camgeom's loader); the board's answers
//! (`CACK`) in a stream are printed; over `--tcp` a local listener plays the board: it reads
//! the commands, answers each, sends frame records, and the monitor's exit status says whether
//! every command was done; over `--serial` a pseudo-terminal's other end plays the board.

use std::io::{Read, Write};
use std::net::TcpListener;

use camgeom::target::TargetState;
use camgeom_fw_app::command::{Ack, AckStatus, COMMAND_LEN, Command, Mode};
use camgeom_fw_app::link::{Deframer, encode_frame, max_frame_len};
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

/// Frames each record in order, numbered from `first`.
fn framed(first: u16, records: &[Vec<u8>]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut buf = [0u8; max_frame_len(RECORD_LEN)];
    for (seq, rec) in (first..).zip(records) {
        let m = encode_frame(seq, rec, &mut buf).unwrap();
        out.extend_from_slice(&buf[..m]);
    }
    out
}

/// The commands in framed bytes, with their sequence numbers, as the board's receiver reads
/// them.
fn read_commands(bytes: &[u8]) -> Vec<(u16, Command)> {
    let mut rx = Deframer::<{ max_frame_len(COMMAND_LEN) }>::new();
    let mut input = bytes;
    let mut out = Vec::new();
    while let Some(f) = rx.push(&mut input) {
        out.push((f.seq, Command::decode(f.record).unwrap()));
    }
    assert_eq!(rx.stats().damaged, 0);
    out
}

fn ack(seq: u16, kind: u32, status: AckStatus) -> Vec<u8> {
    Ack { seq, kind, status }.encode().to_vec()
}

#[test]
fn commands_out_frames_the_commands_the_board_reads() {
    let camera = crate::common::chessboard("camera.json");
    let out_file = scratch_file("commands", "").with_extension("bin");
    let out = camgeom(&[
        "monitor",
        "--set",
        "tag-size=0.08",
        "--set",
        "tag-family=tag25h9",
        "--set",
        "tag-id=7",
        "--set",
        &format!("camera={}", camera.display()),
        "--mode",
        "track-corners",
        "--save",
        "--commands-out",
        out_file.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got = read_commands(&std::fs::read(&out_file).unwrap());
    let json: Value = serde_json::from_str(&std::fs::read_to_string(&camera).unwrap()).unwrap();
    let f = |k: &str| json[k].as_f64().unwrap() as f32;
    let distortion: Vec<f32> = json["distortion"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() as f32)
        .collect();
    let want = [
        Command::SetCamera {
            intrinsics: [f("fx"), f("fy"), f("cx"), f("cy")],
            distortion: distortion.try_into().unwrap(),
        },
        Command::SetTag {
            family: 1,
            id: 7,
            size: 0.08,
        },
        Command::SetMode(Mode::TrackCorners),
        Command::Save,
    ];
    assert_eq!(got, (0..).zip(want).collect::<Vec<_>>());

    // The documented defaults: tag36h11 (family 0), id 0; the size has none.
    let out = camgeom(&[
        "monitor",
        "--set",
        "tag-size=0.1",
        "--commands-out",
        out_file.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let got = read_commands(&std::fs::read(&out_file).unwrap());
    let tag = Command::SetTag {
        family: 0,
        id: 0,
        size: 0.1,
    };
    assert_eq!(got, [(0, tag)]);
    for bad in [
        &["--set", "tag-id=3"][..],
        &["--set", "tag-family=tag99h1", "--set", "tag-size=0.1"],
        &["--set", "tag-size=-1"],
        &["--set", "colour=red"],
        &["--mode", "dance"],
    ] {
        let mut args = vec!["monitor", "--commands-out", out_file.to_str().unwrap()];
        args.extend_from_slice(bad);
        let out = camgeom(&args);
        assert_eq!(out.status.code(), Some(2), "{bad:?}");
    }
    // Nothing is sent to a replayed stream.
    let out = camgeom(&["monitor", "--replay", out_file.to_str().unwrap(), "--save"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn answers_in_a_replayed_stream_are_printed() {
    let records = [
        ack(0, 2, AckStatus::Done),
        frame(0).encode().to_vec(),
        ack(1, 4, AckStatus::FlashFailed),
        frame(1).encode().to_vec(),
    ];
    let got = lines(&framed(0, &records));
    assert_eq!(got[0]["ack"]["seq"], 0);
    assert_eq!(got[0]["ack"]["kind"], "tag");
    assert_eq!(got[0]["ack"]["status"], "done");
    assert_eq!(got[1]["frame"], 0);
    assert_eq!(got[2]["ack"]["kind"], "save");
    assert_eq!(got[2]["ack"]["status"], "flash_failed");
    assert_eq!(got[3]["frame"], 1);
    let link = &got[4]["link"];
    assert_eq!(link["frames"], 4);
    assert_eq!(link["unreadable"], 0, "{link}");
    // No commands were sent: a refusal in a replay is printed, not checked.
    assert_eq!(got.len(), 5);

    let path = scratch_file("acks", "").with_extension("bin");
    std::fs::write(&path, framed(0, &records)).unwrap();
    let out = camgeom(&["monitor", "--replay", path.to_str().unwrap()]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let acks: Vec<&str> = text.lines().filter(|l| l.starts_with("ack:")).collect();
    assert_eq!(
        acks,
        [
            "ack: command 0 tag done",
            "ack: command 1 save flash_failed"
        ]
    );
}

/// A board on a local socket: reads `n` command frames, answers each with `status(seq,
/// command)`, sends three frame records and closes. Returns the commands it read and the
/// monitor's output.
fn board_session(
    n: usize,
    args: &[&str],
    status: fn(u16) -> AckStatus,
) -> (Vec<(u16, Command)>, std::process::Output) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    let board = std::thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        s.set_read_timeout(Some(std::time::Duration::from_secs(20)))
            .unwrap();
        let mut rx = Deframer::<{ max_frame_len(COMMAND_LEN) }>::new();
        let mut got = Vec::new();
        let mut buf = [0u8; 64];
        while got.len() < n {
            let k = s.read(&mut buf).unwrap();
            assert!(k > 0, "the monitor closed before sending {n} commands");
            let mut input = &buf[..k];
            while let Some(f) = rx.push(&mut input) {
                got.push((f.seq, Command::decode(f.record).unwrap()));
            }
        }
        let mut records: Vec<Vec<u8>> = got
            .iter()
            .map(|(seq, c)| ack(*seq, c.kind(), status(*seq)))
            .collect();
        records.extend((0..3).map(|k| frame(k).encode().to_vec()));
        s.write_all(&framed(100, &records)).unwrap();
        got
    });
    let mut all = vec!["monitor", "--tcp", &addr];
    all.extend_from_slice(args);
    let out = camgeom(&all);
    (board.join().unwrap(), out)
}

#[test]
fn commands_go_to_a_board_over_tcp_and_its_answers_are_checked() {
    let args = [
        "--set",
        "tag-size=0.05",
        "--set",
        "tag-id=12",
        "--mode",
        "track-tag",
        "--save",
    ];
    let (got, out) = board_session(3, &args, |_| AckStatus::Done);
    assert_eq!(
        got,
        [
            (
                0,
                Command::SetTag {
                    family: 0,
                    id: 12,
                    size: 0.05
                }
            ),
            (1, Command::SetMode(Mode::TrackTag)),
            (2, Command::Save),
        ]
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines.contains(&"ack: command 0 tag done"), "{text}");
    assert!(lines.contains(&"ack: command 1 mode done"), "{text}");
    assert!(lines.contains(&"ack: command 2 save done"), "{text}");
    // The three frame rows (the table's columns), after the header.
    assert_eq!(
        lines
            .iter()
            .filter(|l| l.split('\t').count() == 14 && !l.starts_with("seq"))
            .count(),
        3
    );
    assert_eq!(lines.last(), Some(&"commands: 3 sent, 3 done"), "{text}");

    // The board refuses the mode: the monitor still prints everything, and fails.
    let (_, out) = board_session(2, &["--json", "--mode", "calibrate", "--save"], |seq| {
        if seq == 0 {
            AckStatus::Unsupported
        } else {
            AckStatus::Done
        }
    });
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8(out.stdout).unwrap();
    let got: Vec<Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(got[0]["ack"]["status"], "unsupported");
    assert_eq!(got.iter().filter(|v| v.get("frame").is_some()).count(), 3);
    let commands = &got.last().unwrap()["commands"];
    assert_eq!(commands["sent"], 2, "{commands}");
    assert_eq!(commands["done"], 1, "{commands}");
    assert_eq!(commands["not_done"][0]["kind"], "mode", "{commands}");
    assert_eq!(
        commands["not_done"][0]["status"], "unsupported",
        "{commands}"
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("1 of 2 commands not done"));
}

/// `--serial`: a pseudo-terminal plays the board's port (its other end the board), which reads
/// the commands, answers them and sends frame records; the monitor stops after `--seconds`.
#[cfg(target_os = "linux")]
#[test]
fn commands_go_to_a_board_over_a_serial_port() {
    use rustix::pty::{OpenptFlags, grantpt, openpt, ptsname, unlockpt};
    let master = openpt(OpenptFlags::RDWR | OpenptFlags::NOCTTY).unwrap();
    grantpt(&master).unwrap();
    unlockpt(&master).unwrap();
    let port = ptsname(&master, Vec::new()).unwrap().into_string().unwrap();
    // Held open so that the board's end never sees the port hang up between the monitor's
    // open and close.
    let _slave = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&port)
        .unwrap();
    let mut master = std::fs::File::from(master);
    // The board, on its own thread: a monitor that fails leaves it waiting, not the test.
    let board = std::thread::spawn(move || {
        let mut rx = Deframer::<{ max_frame_len(COMMAND_LEN) }>::new();
        let mut got = Vec::new();
        let mut buf = [0u8; 64];
        while got.len() < 2 {
            let k = master.read(&mut buf).unwrap();
            let mut input = &buf[..k];
            while let Some(f) = rx.push(&mut input) {
                got.push((f.seq, Command::decode(f.record).unwrap()));
            }
        }
        let records = [
            ack(0, 2, AckStatus::Done),
            ack(1, 4, AckStatus::Done),
            frame(0).encode().to_vec(),
        ];
        master.write_all(&framed(0, &records)).unwrap();
        // The port stays open until the monitor has read it.
        (got, master)
    });
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_camgeom"))
        .args([
            "monitor",
            "--serial",
            &port,
            "--baud",
            "921600",
            "--seconds",
            "4",
            "--set",
            "tag-size=0.08",
            "--save",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (got, _master) = board.join().unwrap();
    let tag = Command::SetTag {
        family: 0,
        id: 0,
        size: 0.08,
    };
    assert_eq!(got, [(0, tag), (1, Command::Save)]);
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines.contains(&"ack: command 1 save done"), "{text}");
    assert_eq!(lines.last(), Some(&"commands: 2 sent, 2 done"), "{text}");
    assert!(
        lines
            .iter()
            .any(|l| l.starts_with("link: 3 frames, 0 damaged")),
        "{text}"
    );
}

/// A board that sends two frame records and then stops talking without closing the socket:
/// `--idle` ends the monitor while the board still holds the connection open (the board waits
/// for the test to say it may close); a board that closes ends it without any limit.
#[test]
fn a_stalled_or_closed_board_ends_the_monitor() {
    for stall in [true, false] {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let (done_tx, done_rx) = std::sync::mpsc::channel::<()>();
        let board = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            let records: Vec<Vec<u8>> = (0..2).map(|k| frame(k).encode().to_vec()).collect();
            s.write_all(&framed(0, &records)).unwrap();
            if stall {
                // Until the monitor has returned (a minute at most, so a monitor that hangs
                // fails the test rather than blocking it).
                let _ = done_rx.recv_timeout(std::time::Duration::from_secs(60));
            }
        });
        let mut args = vec!["monitor", "--json", "--tcp", &addr];
        if stall {
            args.extend(["--idle", "0.3"]);
        }
        let out = camgeom(&args);
        let _ = done_tx.send(());
        board.join().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let got: Vec<Value> = String::from_utf8(out.stdout)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(got.iter().filter(|v| v.get("frame").is_some()).count(), 2);
        assert_eq!(got.last().unwrap()["link"]["frames"], 2, "stall {stall}");
    }
}

/// `--frames-dir`: a board streaming frames sends its settings, each frame's pixel chunks,
/// then the frame's record. Frame 0 comes whole and is written with its overlay (the outline
/// in green, everything else the frame's grey); frame 1 loses a chunk and frame 2 its record:
/// both counted incomplete, neither written.
#[test]
fn streamed_frames_are_written_with_their_overlay() {
    use camgeom_fw_app::frame_chunk::send_frame;
    use camgeom_fw_app::settings::Settings;
    let (w, h) = (40usize, 30usize);
    let pixels: Vec<u8> = (0..w * h).map(|k| (k % 7 * 20 + 30) as u8).collect();
    let img = camgeom::image::ImageView::packed(&pixels, w, h).unwrap();
    let settings = Settings {
        mode: Mode::StreamFrames,
        family: 0,
        id: 1,
        tag_size: 0.1,
        intrinsics: [50.0, 50.0, 19.5, 14.5],
        distortion: [0.0; 5],
        chessboard: camgeom_fw_app::command::ChessboardSettings::DEFAULT,
    };
    let outline = [[5.0, 5.0], [30.0, 5.0], [30.0, 22.0], [5.0, 22.0]];
    let mut records: Vec<Vec<u8>> = Vec::new();
    for k in 0..3u32 {
        records.push(settings.encode().to_vec());
        let mut chunks = Vec::new();
        send_frame(k, &img, |c| chunks.push(c.to_vec())).unwrap();
        assert_eq!(chunks.len(), 10);
        if k == 1 {
            chunks.remove(4);
        }
        records.extend(chunks);
        if k != 2 {
            records.push(
                FrameRecord {
                    outline: Some(outline),
                    ..frame(k)
                }
                .encode()
                .to_vec(),
            );
        }
    }
    let path = scratch_file("frames-stream", "").with_extension("bin");
    std::fs::write(&path, framed(0, &records)).unwrap();
    let dir = scratch_file("frames-dir", "").with_extension("dir");
    let _ = std::fs::remove_dir_all(&dir);
    let out = camgeom(&[
        "monitor",
        "--json",
        "--replay",
        path.to_str().unwrap(),
        "--frames-dir",
        dir.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got: Vec<Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let pictures = got
        .iter()
        .find_map(|v| v.get("pictures"))
        .expect("a pictures line");
    assert_eq!(pictures["written"], 1, "{pictures}");
    assert_eq!(pictures["incomplete"], 2, "{pictures}");
    let link = &got.last().unwrap()["link"];
    assert_eq!(link["unreadable"], 0, "{link}");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["frame-000000.png"]);
    let png = image::open(dir.join(&names[0])).unwrap().to_rgb8();
    assert_eq!((png.width() as usize, png.height() as usize), (w, h));
    let (mut grey, mut green) = (0, 0);
    for (x, y, p) in png.enumerate_pixels() {
        let v = pixels[y as usize * w + x as usize];
        if p.0 == [v, v, v] {
            grey += 1;
        } else if p.0 == [40, 230, 40] {
            green += 1;
        }
    }
    // The outline's 4 edges (about 84 pixels) in green, with a dark halo; the rest the frame.
    assert!(green >= 60, "{green} green pixels");
    assert!(grey >= w * h - 4 * green, "{grey} grey pixels");
}

/// A board in calibrate mode (`--mode calibrate`): its progress records come out a line each
/// (views kept of needed), then the result (K, distortion, RMS), the verdict and the settings
/// it runs with; `--set chessboard=7x5 --set views=12` travels as one chessboard command.
#[test]
fn a_calibrate_session_shows_its_progress_and_result() {
    use camgeom_fw_app::calibrate_mode::{ProgressRecord, Status, encode_result};
    use camgeom_fw_app::calibration::{CalibRecord, VIEWS};
    use camgeom_fw_app::command::ChessboardSettings;
    use camgeom_fw_app::settings::Settings;
    let progress = |frame, found, kept, views, status| ProgressRecord {
        frame,
        found,
        kept,
        views,
        needed: 2,
        status,
        reason: 0,
        error: 0,
        cost: 7,
    };
    let result = CalibRecord {
        views_used: 2,
        iterations: 6,
        cost: 0,
        warnings: 0,
        intrinsics: [266.5, 266.25, 160.5, 118.75],
        distortion: [-0.25, 0.125, 0.0, 0.0, -0.0625],
        rms_px: 0.125,
        initial_rms_px: 0.5,
        std: [0.5; 9],
        per_view_rms_px: [0.1; VIEWS],
        stack: 0,
    };
    let settings = Settings {
        mode: Mode::TrackTag,
        family: 0,
        id: 1,
        tag_size: 0.1,
        intrinsics: result.intrinsics,
        distortion: result.distortion,
        chessboard: ChessboardSettings::DEFAULT,
    };
    let records = vec![
        ack(0, 2, AckStatus::Done),
        progress(1, false, false, 0, Status::Collecting)
            .encode()
            .to_vec(),
        progress(2, true, true, 1, Status::Collecting)
            .encode()
            .to_vec(),
        progress(3, true, false, 1, Status::Collecting)
            .encode()
            .to_vec(),
        progress(4, true, true, 2, Status::Collecting)
            .encode()
            .to_vec(),
        encode_result(&result).to_vec(),
        progress(4, false, false, 2, Status::Calibrated)
            .encode()
            .to_vec(),
        settings.encode().to_vec(),
    ];
    let path = scratch_file("calibrate-stream", "").with_extension("bin");
    std::fs::write(&path, framed(0, &records)).unwrap();
    let out = camgeom(&["monitor", "--json", "--replay", path.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got: Vec<Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let cal: Vec<&Value> = got.iter().filter_map(|v| v.get("calibrate")).collect();
    assert_eq!(cal.len(), 5);
    assert_eq!(cal[1]["kept"], true);
    assert_eq!(cal[3]["views"], 2);
    assert_eq!(cal[4]["status"], "calibrated");
    let r = got
        .iter()
        .find_map(|v| v.get("calibration"))
        .expect("a result line");
    assert_eq!(r["intrinsics"][0], 266.5);
    assert_eq!(r["rms_px"], 0.125);
    let s = got
        .iter()
        .find_map(|v| v.get("settings"))
        .expect("a settings line");
    assert_eq!(
        (s["mode"].as_str(), s["intrinsics"][3].as_f64()),
        (Some("track-tag"), Some(118.75))
    );
    assert_eq!(got.last().unwrap()["link"]["unreadable"], 0);
    let table = camgeom(&["monitor", "--replay", path.to_str().unwrap()]);
    let text = String::from_utf8(table.stdout).unwrap();
    assert!(
        text.contains("calibrate: frame 2 board found, kept, 1 of 2 views"),
        "{text}"
    );
    assert!(
        text.contains("calibrate: calibrated after 4 frames, 2 of 2 views"),
        "{text}"
    );
    assert!(text.contains("calibration: 2 views, fx 266.50"), "{text}");
    // The chessboard's keys: one command, before the mode.
    let cmds = scratch_file("calibrate-commands", "").with_extension("bin");
    let out = camgeom(&[
        "monitor",
        "--set",
        "chessboard=7x5",
        "--set",
        "views=12",
        "--mode",
        "calibrate",
        "--commands-out",
        cmds.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let sent = read_commands(&std::fs::read(&cmds).unwrap());
    let board = ChessboardSettings {
        cols: 7,
        rows: 5,
        views: 12,
        ..ChessboardSettings::DEFAULT
    };
    assert_eq!(
        sent,
        [
            (0, Command::SetChessboard(board)),
            (1, Command::SetMode(Mode::Calibrate))
        ]
    );
    let bad = camgeom(&[
        "monitor",
        "--set",
        "views=40",
        "--commands-out",
        cmds.to_str().unwrap(),
    ]);
    assert_eq!(
        bad.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
}
