//! Pyramidal Lucas-Kanade between two frames of the bundled box sequence, in Q16.16 fixed
//! point (the board's arithmetic) and in f32, from Shi-Tomasi corners of the first.
//!
//! `cargo run --example klt_two_frames`

#[path = "common.rs"]
mod common;

use camgeom::corners::{Corner, CornerConfig, good_features, scratch_len as corner_scratch_len};
use camgeom::heapless::Vec as FixedVec;
use camgeom::image::ImageView;
use camgeom::klt::{
    Borders, Fixed, Flow, FlowStatus, Gradients, LkConfig, Q16, calc_flow, scratch_len,
};
use camgeom::pyramid::{Pyramid, buffer_len};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = common::data_dir().join("sequences/box");
    let (w, h, a) = common::read_gray_png(&dir.join("0000.png"))?;
    let (_, _, b) = common::read_gray_png(&dir.join("0001.png"))?;
    let (va, vb) = (ImageView::packed(&a, w, h)?, ImageView::packed(&b, w, h)?);
    // 100 corners, at least 8 px apart.
    let mut corners: FixedVec<Corner, 100> = FixedVec::new();
    let mut candidates = vec![Corner::default(); 1024];
    let mut cscratch = vec![0u32; corner_scratch_len(w)];
    let ccfg = CornerConfig {
        min_distance: 8,
        ..CornerConfig::default()
    }
    .check()?;
    good_features(
        &va,
        &ccfg,
        core::iter::empty(),
        &mut corners,
        &mut candidates,
        &mut cscratch,
    )?;
    // OpenCV's calcOpticalFlowPyrLK defaults: 21x21 windows, 4 levels, 30 iterations / 0.01 px.
    let params = LkConfig::default().check()?;
    let levels = params.config().max_level + 1;
    let (mut ba, mut bb) = (
        vec![0u8; buffer_len(w, h, levels)],
        vec![0u8; buffer_len(w, h, levels)],
    );
    let pa = Pyramid::build(va, &mut ba, levels)?;
    let pb = Pyramid::build(vb, &mut bb, levels)?;
    let mut scratch = vec![0i16; scratch_len(params.config().win)];
    let fixed: Vec<[Q16; 2]> = corners
        .iter()
        .map(|c| {
            [
                Q16::from_bits(i32::from(c.x) << 16),
                Q16::from_bits(i32::from(c.y) << 16),
            ]
        })
        .collect();
    let mut fixed_out = vec![Flow::default(); fixed.len()];
    calc_flow::<Fixed>(
        &pa,
        &pb,
        &fixed,
        &mut fixed_out,
        &params,
        Gradients::PerWindow,
        Borders::None,
        &mut scratch,
    )?;
    let float: Vec<[f32; 2]> = corners
        .iter()
        .map(|c| [f32::from(c.x), f32::from(c.y)])
        .collect();
    let mut float_out = vec![Flow::default(); float.len()];
    calc_flow::<f32>(
        &pa,
        &pb,
        &float,
        &mut float_out,
        &params,
        Gradients::PerWindow,
        Borders::None,
        &mut scratch,
    )?;
    let mut tracked = 0;
    let mut gap = 0.0f32;
    for (q, f) in fixed_out.iter().zip(&float_out) {
        if q.status == FlowStatus::Tracked && f.status == FlowStatus::Tracked {
            tracked += 1;
            let dx = Q16::to_f32(q.x) - f.x;
            let dy = Q16::to_f32(q.y) - f.y;
            gap = gap.max(dx.hypot(dy));
        }
    }
    let mean_motion: f32 = float_out
        .iter()
        .zip(&float)
        .filter(|(f, _)| f.status == FlowStatus::Tracked)
        .map(|(f, p)| (f.x - p[0]).hypot(f.y - p[1]))
        .sum::<f32>()
        / tracked.max(1) as f32;
    println!("{} corners, {tracked} tracked by both paths", corners.len());
    println!("mean motion {mean_motion:.2} px; fixed point and f32 differ by at most {gap:.4} px");
    Ok(())
}
