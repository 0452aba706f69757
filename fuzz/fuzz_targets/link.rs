//! The board's record stream (`camgeom_fw_app::link`) on arbitrary bytes: a stream of frames
//! built from arbitrary records and sequence numbers, then damaged by arbitrary edits (flips,
//! drops, repeats, inserted bytes) and fed to a `Deframer` in arbitrary chunks; and the same
//! receiver on raw arbitrary bytes. Contract: no panic; a clean stream decodes whole; the
//! counts add up; `encode_frame` into a short buffer is an error, not a panic. That a damaged
//! stream delivers only frames that were sent is a property against random damage (CRC-32
//! misses one random error in 2^32), not against crafted bytes: the fuzzer forges frames by
//! reading the CRC comparison (a 2-byte record behind a code byte it moved). The unit tests
//! and the main job's link-fault table check it on seeded random damage.
#![no_main]

use arbitrary::Arbitrary;
use camgeom_fw_app::link::{Deframer, LinkError, encode_frame, max_frame_len};
use libfuzzer_sys::fuzz_target;

/// The longest record the fuzzer sends, and the receiver's room (sometimes too little).
const MAX_RECORD: usize = 300;

#[derive(Debug, Arbitrary)]
enum Edit {
    Flip(u16, u8),
    Drop(u16),
    Repeat(u16),
    Insert(u16, u8),
}

#[derive(Debug, Arbitrary)]
struct Input {
    records: Vec<(u16, Vec<u8>)>,
    edits: Vec<Edit>,
    chunks: Vec<u8>,
    raw: Vec<u8>,
    short_out: u8,
}

fn feed<const N: usize>(bytes: &[u8], chunks: &[u8]) -> (Vec<(u16, Vec<u8>)>, u32) {
    let mut d = Deframer::<N>::new();
    let mut got = Vec::new();
    let mut rest = bytes;
    let mut sizes = chunks.iter().cycle();
    while !rest.is_empty() {
        let n = (usize::from(sizes.next().copied().unwrap_or(255)) + 1).min(rest.len());
        let (mut chunk, tail) = rest.split_at(n);
        rest = tail;
        while let Some(f) = d.push(&mut chunk) {
            got.push((f.seq, f.record.to_vec()));
        }
        assert!(chunk.is_empty());
    }
    let s = d.stats();
    assert_eq!(s.frames as usize, got.len());
    (got, s.damaged)
}

fuzz_target!(|inp: Input| {
    let mut sent: Vec<(u16, Vec<u8>)> = Vec::new();
    let mut stream = Vec::new();
    let mut buf = [0u8; max_frame_len(MAX_RECORD)];
    for (seq, mut rec) in inp.records.into_iter().take(64) {
        rec.truncate(MAX_RECORD);
        let n = encode_frame(seq, &rec, &mut buf).expect("max_frame_len suffices");
        assert_eq!(buf[..n].iter().filter(|&&b| b == 0).count(), 1);
        assert_eq!(buf[n - 1], 0);
        stream.extend_from_slice(&buf[..n]);
        sent.push((seq, rec));
    }
    // A buffer shorter than the frame: an error.
    let short = usize::from(inp.short_out) % max_frame_len(8);
    let mut small = vec![0u8; short];
    match encode_frame(1, &[0xaa; 8], &mut small) {
        Ok(n) => assert!(n <= short && short >= 8 + 6 + 2),
        Err(LinkError::BufferTooSmall) => {}
        Err(e) => panic!("undocumented error {e:?}"),
    }
    // The clean stream decodes whole when no two consecutive frames share a sequence number.
    let distinct = sent.windows(2).all(|w| w[0].0 != w[1].0);
    let (got, damaged) = feed::<{ max_frame_len(MAX_RECORD) }>(&stream, &inp.chunks);
    if distinct {
        assert_eq!(got, sent);
        assert_eq!(damaged, 0);
    }
    // Damaged: anything but a panic; every delivered frame is counted.
    for e in inp.edits.iter().take(32) {
        if stream.is_empty() {
            break;
        }
        let at = |i: u16| usize::from(i) % stream.len();
        match *e {
            Edit::Flip(i, b) => {
                let k = at(i);
                stream[k] ^= b.max(1);
            }
            Edit::Drop(i) => {
                stream.remove(at(i));
            }
            Edit::Repeat(i) => {
                let k = at(i);
                stream.insert(k, stream[k]);
            }
            Edit::Insert(i, b) => stream.insert(at(i), b),
        }
    }
    let _ = feed::<{ max_frame_len(MAX_RECORD) }>(&stream, &inp.chunks);
    let _ = feed::<64>(&stream, &inp.chunks);
    // Raw bytes: anything, never a panic.
    let _ = feed::<{ max_frame_len(MAX_RECORD) }>(&inp.raw, &inp.chunks);
    let _ = feed::<1>(&inp.raw, &inp.chunks);
});
