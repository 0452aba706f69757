//! Undistortion (`remap`): the new camera matrix of arbitrary (singular, extreme, non-finite)
//! Brown-Conrady and fisheye cameras with an arbitrary `alpha` / balance, the full (Q10.5 and
//! wide) and the grid map for arbitrary sizes and buffers, and both remaps between arbitrary source and
//! destination frames. Contract (module docs): no panic; a new camera matrix is finite with
//! positive focal lengths, or `InvalidParameter("alpha")` for `alpha` outside `[0, 1]`; map
//! entries are `INVALID` or in range; every remapped pixel is a convex combination of source
//! pixels and the border value (so between their minimum and maximum), and an `INVALID` entry
//! gives the border; the documented errors for bad sizes and short buffers.
#![no_main]

use arbitrary::Arbitrary;
use camgeom::Error;
use camgeom::Real;
use camgeom::camera::{Camera, Distortion, Fisheye, Intrinsics};
use camgeom::image::{ImageMut, ImageView};
use camgeom::remap::{
    GridMap, INVALID, MAX_MAP_DIM, MapEntry, WideEntry, build_map, grid_len, map_len,
    new_camera_matrix, remap,
};
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::Num;

#[derive(Debug, Arbitrary)]
enum Lens {
    /// Brown-Conrady coefficients, 1/256 steps.
    Small([i8; 5]),
    /// Fisheye coefficients, 1/256 steps.
    Fisheye([i8; 4]),
    /// Arbitrary Brown-Conrady coefficients.
    Any([Num; 5]),
}

#[derive(Debug, Arbitrary)]
struct Input {
    f64: bool,
    /// `Some`: arbitrary intrinsics; `None`: a plausible camera for the frame.
    k: Option<[Num; 4]>,
    f: u8,
    lens: Lens,
    alpha: Num,
    /// Destination (undistorted) frame; source frame.
    dst: (u16, u16),
    src: (u8, u8, u8),
    map_slack: i16,
    shift: u8,
    grid_slack: i16,
    border: u8,
    pixels: std::vec::Vec<u8>,
    /// Use the camera's own matrix rather than the new one.
    own_k: bool,
}

fn lit<T: Real>(v: f32) -> T {
    T::lit(f64::from(v))
}

fn in_range(out: &[u8], src: &[u8], border: u8, what: &str) {
    let lo = src.iter().copied().chain([border]).min().unwrap_or(border);
    let hi = src.iter().copied().chain([border]).max().unwrap_or(border);
    for &o in out {
        assert!(o >= lo && o <= hi, "{what}: {o} outside [{lo}, {hi}]");
    }
}

fn run<T: Real>(inp: &Input) {
    // Frames: destination up to 1100 (past MAX_MAP_DIM) on a side but at most 16 K pixels
    // of buffer; the source from the fuzzer's bytes.
    let (dw, dh) = (usize::from(inp.dst.0 % 1100), usize::from(inp.dst.1 % 1100));
    let (sw, sh) = (usize::from(inp.src.0), usize::from(inp.src.1));
    let sstride = sw + usize::from(inp.src.2 % 4);
    let src: std::vec::Vec<u8> = (0..sstride * sh)
        .map(|i| {
            inp.pixels
                .get(i % inp.pixels.len().max(1))
                .copied()
                .unwrap_or(0)
        })
        .collect();
    let Ok(sview) = ImageView::new(&src[..], sw, sh, sstride) else {
        return;
    };

    let (w, h) = (dw.max(1) as f32, dh.max(1) as f32);
    let k = match inp.k {
        Some(k) => Intrinsics::new(
            lit::<T>(k[0].get()),
            lit(k[1].get()),
            lit(k[2].get()),
            lit(k[3].get()),
        ),
        None => {
            let f = 0.25 * w.max(h) * (1.0 + f32::from(inp.f) / 32.0);
            Intrinsics::new(
                lit::<T>(f),
                lit(f),
                lit((w - 1.0) / 2.0),
                lit((h - 1.0) / 2.0),
            )
        }
    };
    let Ok(k) = k else { return };
    let camera = match &inp.lens {
        Lens::Small(c) => Distortion::from_opencv(c.map(|v| lit::<T>(f32::from(v) / 256.0)))
            .map(|d| Camera::new(k, d)),
        Lens::Any(c) => {
            Distortion::from_opencv(c.map(|v| lit::<T>(v.get()))).map(|d| Camera::new(k, d))
        }
        Lens::Fisheye(c) => Fisheye::from_opencv(c.map(|v| lit::<T>(f32::from(v) / 256.0)))
            .map(|f| Camera::fisheye(k, f)),
    };
    let Ok(camera) = camera else { return };

    let alpha: T = lit(inp.alpha.get());
    let k_new = match new_camera_matrix(&camera, dw, dh, alpha) {
        Ok(kn) => {
            let v = [kn.fx(), kn.fy(), kn.cx(), kn.cy(), kn.skew()];
            assert!(v.iter().all(|x| x.finite()), "new_camera_matrix: {v:?}");
            assert!(
                kn.fx() > T::zero() && kn.fy() > T::zero(),
                "new_camera_matrix: {v:?}"
            );
            kn
        }
        Err(Error::InvalidParameter("alpha")) => {
            assert!(
                !(alpha >= T::zero() && alpha <= T::one()),
                "alpha {alpha:?} refused"
            );
            return;
        }
        Err(Error::InvalidImage) => return assert!(dw == 0 || dh == 0),
        Err(_) => {
            if !inp.own_k {
                return;
            }
            k
        }
    };
    let k_new = if inp.own_k { k } else { k_new };

    // The full map.
    let need = map_len(dw, dh);
    let mlen = (need.min(16 << 10) as i64 + i64::from(inp.map_slack)).max(0) as usize;
    let mut map = std::vec![[0i16; 2]; mlen];
    let bad_size = dw == 0 || dh == 0 || dw > MAX_MAP_DIM || dh > MAX_MAP_DIM;
    // The destination, when it is small enough to remap (at most 64 K pixels).
    let mut out = std::vec![0u8; if dw * dh <= 1 << 16 { dw * dh } else { 0 }];
    match build_map(&camera, &k_new, dw, dh, &mut map) {
        Ok(()) => {
            assert!(!bad_size && mlen >= need);
            for m in &map[..need] {
                assert!(
                    *m == INVALID || (m[0] > i16::MIN && m[1] > i16::MIN),
                    "entry {m:?}"
                );
            }
            let Ok(mut dview) = ImageMut::packed(&mut out[..], dw, dh) else {
                panic!("destination {dw}x{dh}");
            };
            match remap(&sview, &map, &mut dview, inp.border) {
                Ok(()) => {
                    in_range(&out, &src, inp.border, "remap");
                    for (o, m) in out.iter().zip(&map) {
                        if *m == INVALID {
                            assert_eq!(*o, inp.border, "remap: INVALID entry");
                        }
                    }
                }
                Err(e) => panic!("remap: {e:?} with a map of the frame's size"),
            }
            // A map too short for the destination.
            if dh > 1 {
                let mut d = ImageMut::packed(&mut out[..], dw, dh).unwrap();
                assert_eq!(
                    remap(&sview, &map[..need - dw], &mut d, inp.border),
                    Err(Error::BufferTooSmall("map"))
                );
            }
        }
        Err(Error::InvalidImage) => assert!(bad_size),
        Err(Error::BufferTooSmall("map")) => assert!(mlen < need),
        Err(e) => panic!("build_map: undocumented error {e:?}"),
    }

    // The wide map (any frame up to 32767 px): where the Q10.5 map holds a source, the same
    // Q.5 position; its remap between the same bounds, in grey and in RGB.
    let mut wide = std::vec![WideEntry::INVALID; mlen];
    match build_map(&camera, &k_new, dw, dh, &mut wide) {
        Ok(()) => {
            assert!(dw > 0 && dh > 0 && mlen >= need);
            if !bad_size {
                for (n, e) in map[..need].iter().zip(&wide) {
                    if let Some(q) = n.q5() {
                        assert_eq!(e.q5(), Some(q), "{n:?} {e:?}");
                    }
                }
            }
            if let Ok(mut dview) = ImageMut::packed(&mut out[..], dw, dh) {
                match remap(&sview, &wide, &mut dview, inp.border) {
                    Ok(()) => in_range(&out, &src, inp.border, "remap (wide)"),
                    Err(e) => panic!("remap (wide): {e:?} with a map of the frame's size"),
                }
            }
            let rgb: std::vec::Vec<[u8; 3]> = src.iter().map(|&p| [p, p / 2, 255 - p]).collect();
            let mut orgb = std::vec![[0u8; 3]; out.len()];
            if let (Ok(s3), Ok(mut d3)) = (
                ImageView::new(&rgb[..], sw, sh, sstride),
                ImageMut::packed(&mut orgb[..], dw, dh),
            ) {
                assert_eq!(remap(&s3, &wide, &mut d3, inp.border), Ok(()));
                let grey: std::vec::Vec<u8> = orgb.iter().map(|p| p[0]).collect();
                assert_eq!(grey, out, "RGB channel 0 against the grey remap");
            }
        }
        Err(Error::InvalidImage) => assert!(dw == 0 || dh == 0),
        Err(Error::BufferTooSmall("map")) => assert!(mlen < need),
        Err(e) => panic!("build_map (wide): undocumented error {e:?}"),
    }

    // The grid map.
    let shift = u32::from(inp.shift % 8);
    let glen = if (1..=6).contains(&shift) {
        grid_len(dw, dh, shift)
    } else {
        0
    };
    let glen = (glen.min(8 << 10) as i64 + i64::from(inp.grid_slack)).max(0) as usize;
    let mut nodes = std::vec![[0i32; 2]; glen];
    match GridMap::build(&camera, &k_new, dw, dh, shift, &mut nodes) {
        Ok(g) => {
            assert!(dw > 0 && dh > 0 && (1..=6).contains(&shift));
            out.fill(0);
            let Ok(mut dview) = ImageMut::packed(&mut out[..], dw, dh) else {
                return;
            };
            match g.remap(&sview, &mut dview, inp.border) {
                Ok(()) => in_range(&out, &src, inp.border, "GridMap::remap"),
                Err(e) => panic!("GridMap::remap: {e:?} for a frame of the map's size"),
            }
        }
        Err(Error::InvalidImage) => assert!(dw == 0 || dh == 0),
        Err(Error::InvalidParameter("shift")) => assert!(!(1..=6).contains(&shift)),
        Err(Error::BufferTooSmall("nodes")) => {}
        Err(Error::Degenerate) => {}
        Err(e) => panic!("GridMap::build: undocumented error {e:?}"),
    }
}

fuzz_target!(|inp: Input| {
    if inp.f64 {
        run::<f64>(&inp);
    } else {
        run::<f32>(&inp);
    }
});
