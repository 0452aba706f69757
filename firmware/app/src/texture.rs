//! A textured test frame computed in integers (the board benches' and stack probes' input), for measuring the tracker on a board without
//! image data in flash: `I(x, y) = T(x - dx, y - dy)` for a sub-pixel shift `(dx, dy)` in
//! 1/256 pixel, with `T` a sum of triangle waves of prime periods (corners everywhere,
//! exact sub-pixel motion).

use camgeom::image::ImageMut;

/// Triangle wave of period `2 p` pixels at `u` (1/256 px), in `0 ..= 256 p`.
fn tri(u: i32, p: i32) -> i32 {
    let period = 2 * p * 256;
    let r = u.rem_euclid(period);
    (r - p * 256).abs()
}

/// Fills `frame` with the texture shifted by `(dx, dy)` (1/256 pixel).
pub fn textured_frame(frame: &mut ImageMut<'_, u8>, dx: i32, dy: i32) {
    for y in 0..frame.height() {
        let v = y as i32 * 256 - dy;
        let Some(row) = frame.row_mut(y) else { break };
        for (x, px) in row.iter_mut().enumerate() {
            let u = x as i32 * 256 - dx;
            // Each term below is in 0 ..= 256 p; normalise to 0 ..= 85 and add three.
            let a = tri(u, 13) / 13 * 85 / 256;
            let b = tri(v, 11) / 11 * 85 / 256;
            let c = tri(u + v, 7) / 7 * tri(u - 2 * v, 17) / 17 * 85 / (256 * 256);
            *px = (a + b + c).clamp(0, 255) as u8;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use camgeom::image::ImageView;
    use camgeom::klt::{
        Borders, Fixed, Flow, FlowStatus, Gradients, LkConfig, Q16, calc_flow, scratch_len,
    };
    use camgeom::pyramid::{Pyramid, buffer_len};

    #[test]
    fn shifted_texture_is_tracked() {
        let (w, h) = (160usize, 120usize);
        let mut f0 = std::vec![0u8; w * h];
        let mut f1 = std::vec![0u8; w * h];
        textured_frame(&mut ImageMut::packed(&mut f0, w, h).unwrap(), 0, 0);
        // (1.25, -0.5) px.
        textured_frame(&mut ImageMut::packed(&mut f1, w, h).unwrap(), 320, -128);
        let mut b0 = std::vec![0u8; buffer_len(w, h, 3)];
        let mut b1 = std::vec![0u8; buffer_len(w, h, 3)];
        let p0 = Pyramid::build(ImageView::packed(&f0, w, h).unwrap(), &mut b0, 3).unwrap();
        let p1 = Pyramid::build(ImageView::packed(&f1, w, h).unwrap(), &mut b1, 3).unwrap();
        let pts = [[40, 30], [90, 60], [120, 85]].map(|p| p.map(Q16::from_int));
        let mut f = [Flow::<Q16>::default(); 3];
        let mut s = std::vec![0i16; scratch_len(21)];
        let cfg = LkConfig {
            max_level: 2,
            ..LkConfig::default()
        }
        .check()
        .unwrap();
        calc_flow::<Fixed>(
            &p0,
            &p1,
            &pts,
            &mut f,
            &cfg,
            Gradients::PerWindow,
            Borders::None,
            &mut s,
        )
        .unwrap();
        for (p, r) in pts.iter().zip(&f) {
            assert_eq!(r.status, FlowStatus::Tracked);
            let dx = Q16::to_f32(r.x - p[0]);
            let dy = Q16::to_f32(r.y - p[1]);
            assert!(
                (dx - 1.25).abs() < 0.1 && (dy + 0.5).abs() < 0.1,
                "{dx} {dy}"
            );
        }
    }
}
