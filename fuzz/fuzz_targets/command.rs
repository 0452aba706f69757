//! Commands to the board (`camgeom_fw_app::command`) and its stored settings
//! (`camgeom_fw_app::settings`) on arbitrary bytes: the bytes as a link delivers them, framed
//! and fed in arbitrary chunks to the board's receiver, each frame decoded as a command and
//! applied to settings, which must stay settings a board can run with; and arbitrary bytes
//! read as stored settings (a sector with anything in it); and the same bytes, and arbitrary
//! records, read as a frame's pixel chunk (what the host reads of a board streaming frames).
//! Contract: no panic; every command
//! that decodes round-trips through its bytes and leaves a camera that builds and a tag side
//! that is finite and positive and a calibrate-mode chessboard a board takes (the `chessboard`
//! command); stored settings that decode encode to the same bytes; a chunk
//! that decodes lies inside its frame and encodes to a chunk that decodes the same.
#![no_main]

use arbitrary::Arbitrary;
use camgeom_fw_app::command::{COMMAND_LEN, ChessboardSettings, Command, Mode};
use camgeom_fw_app::frame_chunk::{CHUNK_LEN, FrameChunk};
use camgeom_fw_app::link::{Deframer, max_frame_len};
use camgeom_fw_app::settings::{Applied, SETTINGS_LEN, Settings};
use libfuzzer_sys::fuzz_target;

#[derive(Debug, Arbitrary)]
struct Input {
    link: Vec<u8>,
    chunks: Vec<u8>,
    commands: Vec<[u8; COMMAND_LEN]>,
    stored: [u8; SETTINGS_LEN],
    pixels: Vec<[u8; CHUNK_LEN]>,
}

fn start() -> Settings {
    Settings {
        mode: Mode::TrackTag,
        family: 0,
        id: 0,
        tag_size: 0.08,
        intrinsics: [300.0, 300.0, 160.0, 120.0],
        distortion: [0.0; 5],
        chessboard: ChessboardSettings::DEFAULT,
    }
}

/// A frame's pixel chunk (`camgeom_fw_app::frame_chunk`): one that decodes lies inside its
/// frame and round-trips through its bytes.
fn chunk(record: &[u8]) {
    let Ok(c) = FrameChunk::decode(record) else {
        return;
    };
    assert!(c.offset as usize + c.pixels().len() <= c.frame_len());
    assert!(c.number() < c.count() && !c.pixels().is_empty());
    assert_eq!(FrameChunk::decode(&c.encode()), Ok(c));
}

fn apply(settings: &mut Settings, record: &[u8]) {
    chunk(record);
    let Ok(c) = Command::decode(record) else {
        return;
    };
    assert_eq!(Command::decode(&c.encode()), Ok(c));
    if settings.apply(&c) == Applied::Save {
        assert_eq!(Settings::decode(&settings.encode()), Ok(*settings));
    }
    assert!(settings.camera().is_ok());
    assert!(settings.tag_size.is_finite() && settings.tag_size > 0.0);
    assert_eq!(settings.chessboard.check(), Ok(()));
}

fuzz_target!(|input: Input| {
    let mut settings = start();
    let mut rx = Deframer::<{ max_frame_len(COMMAND_LEN) }>::new();
    let mut rest = input.link.as_slice();
    let mut sizes = input.chunks.iter().cycle();
    while !rest.is_empty() {
        let n = (usize::from(sizes.next().copied().unwrap_or(255)) + 1).min(rest.len());
        let (mut chunk, tail) = rest.split_at(n);
        rest = tail;
        while let Some(f) = rx.push(&mut chunk) {
            apply(&mut settings, f.record);
        }
    }
    for c in &input.commands {
        apply(&mut settings, c);
    }
    for c in &input.pixels {
        chunk(c);
    }
    if let Ok(s) = Settings::decode(&input.stored) {
        assert_eq!(s.encode(), input.stored);
        assert!(s.camera().is_ok());
    }
});
