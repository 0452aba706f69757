//! Full-resolution work on one quad: edge refinement and payload decoding.
//!
//! **Edge refinement** (AprilTag's `refine_edges`): along each edge, at `max(16, len / 8)`
//! points, the image is sampled across the edge every 1/4 pixel over `±(d + 1)` pixels (`d` the
//! decimation), with the difference `g = I(s + n̂) - I(s - n̂)` (bilinear) at each offset `s`
//! (`n̂` the outward normal); offsets where the intensity rises outward are averaged with weight
//! `g²`, giving one edge point; a line is fitted to the points of each edge and consecutive
//! lines are intersected into the new corners.
//!
//! **Decoding** (AprilTag's `quad_decode`): with `H` mapping tag coordinates `(-1, -1)..(1, 1)`
//! (the border's outer edge) to pixels, the cells just outside and just inside the border are
//! sampled (nearest pixel) and two planar intensity models `I = a x + b y + c` are fitted, one
//! for white and one for black (least squares, 3x3 Cholesky); each payload cell is read
//! bilinearly at its centre against the mean of the two models there, the readings are
//! sharpened (`v + s ∇²v`, the 4-neighbour Laplacian over the cell grid) and their signs give
//! the code. The decision margin is `min(mean white excess, mean black excess)`.
//!
//! For an ArUco dictionary the border cells are read the same way (centre, against the
//! models, sharpened with the payload): those read white are OpenCV's border errors
//! (`_getBorderErrors`), which the detector bounds by `maxErroneousBitsInBorderRate`. For a
//! family whose border is wider than one cell ([`Family::border_bits`]) the rings inside the
//! outer one are read too (against the models, not sharpened, the payload read as for a
//! 1-cell border): each read white is a wrong bit, which the detector counts with the
//! payload's against its correction bound. Without it, a 1-cell-border tag36h11 read as the
//! 2-cell family is a scaled copy of its own payload, within 2 bits of its code for some ids.
//!
//! Coordinates are camgeom's: pixel `(i, j)` has its centre at `(i, j)`. AprilTag's pixel
//! centres are at `(i + 0.5, j + 0.5)`; the sampling positions here are AprilTag's shifted by
//! that half pixel, so both read the same pixels.

use nalgebra::Matrix3;

use super::family::Family;
use super::geom::{Line, LineMoments, at4, intersect, project};
use super::quad::Quad;
use crate::image::ImageView;
use crate::scalar::{above, at_most};

/// Samples along an edge normal in [`refine_edges`]: `2 · 4 (d + 1) + 1 + 8` for decimation
/// `d` up to 8 (`DetectorConfig::decimate`'s bound).
const MAX_ALONG: usize = 8 * (8 + 1) + 9;

/// Refines the corners of `q` (full-resolution coordinates) on `img` (module docs). A corner
/// whose two lines cannot be intersected stays where it was.
pub(crate) fn refine_edges(img: &ImageView<'_, u8>, q: &mut Quad, decimate: usize) {
    let _ = refine_edges_with(img, q, decimate, 16);
}

/// How well the edges of [`refine_edges_with`] were measured.
#[derive(Debug, Clone, Copy)]
pub(crate) struct EdgeFit {
    /// The largest mean squared distance of an edge's points from its fitted line (px²).
    pub(crate) worst_mse: f32,
    /// The smallest share of an edge's sample positions that gave an edge point.
    pub(crate) fewest: f32,
}

/// [`refine_edges`] with at least `min_points` edge points an edge (AprilTag: 16); tells how
/// well the edges were measured.
pub(crate) fn refine_edges_with(
    img: &ImageView<'_, u8>,
    q: &mut Quad,
    decimate: usize,
    min_points: usize,
) -> EdgeFit {
    let mut fit = EdgeFit {
        worst_mse: 0.0,
        fewest: 1.0,
    };
    let mut lines = [Line::ZERO; 4];
    for (edge, line) in lines.iter_mut().enumerate() {
        let (pa, pb) = (at4(&q.p, edge), at4(&q.p, edge + 1));
        let (mut nx, mut ny) = (pb.y - pa.y, -(pb.x - pa.x));
        let mag = libm::sqrtf(nx * nx + ny * ny);
        if !above(mag, 0.0) {
            *line = Line {
                ex: pa.x,
                ey: pa.y,
                nx: 0.0,
                ny: 0.0,
            };
            fit.fewest = 0.0;
            continue;
        }
        nx /= mag;
        ny /= mag;
        if q.reversed_border {
            nx = -nx;
            ny = -ny;
        }
        // Without enough edge points the edge keeps its line.
        *line = Line {
            ex: 0.5 * (pa.x + pb.x),
            ey: 0.5 * (pa.y + pb.y),
            nx,
            ny,
        };
        // An edge of a quad the caller predicted can be any length; one in the image is
        // shorter than its width plus height, and samples outside it read nothing: the bound
        // keeps the loop finite for any quad and changes nothing for one in the image.
        let longest = (img.width() + img.height()) as f32;
        let nsamples = ((mag.min(longest) / 8.0) as usize).max(min_points);
        // Relative to the edge midpoint: small numbers keep the f32 covariance exact enough.
        let mut m = LineMoments::new(line.ex, line.ey);
        for s in 0..nsamples {
            let alpha = (1.0 + s as f32) / (nsamples as f32 + 1.0);
            let x0 = alpha * pa.x + (1.0 - alpha) * pb.x;
            let y0 = alpha * pa.y + (1.0 - alpha) * pb.y;
            let Some(EdgePoint { offset: n0, .. }) = edge_point(img, x0, y0, nx, ny, decimate)
            else {
                continue;
            };
            m.add(x0 + n0 * nx, y0 + n0 * ny);
        }
        fit.fewest = fit.fewest.min(m.count as f32 / nsamples as f32);
        // The normal of the fit (AprilTag: the angle ½ atan2(-2 Cxy, Cyy - Cxx); the same
        // direction from the eigenvectors, as the quad fit computes it).
        let Some((fitted, mse)) = m.fit() else {
            continue;
        };
        fit.worst_mse = fit.worst_mse.max(mse);
        *line = fitted;
    }
    let old = q.p;
    for (i, p) in q.p.iter_mut().enumerate() {
        // Corner i joins edge i - 1 (from corner i - 1) and edge i.
        *p = intersect(&at4(&lines, i + 3), &at4(&lines, i)).unwrap_or(at4(&old, i));
    }
    fit
}

/// One edge point of [`refine_edges_with`]: where, along the unit normal `(nx, ny)` through
/// `(x0, y0)`, the intensity rises outward (`offset`, pixels from `(x0, y0)`), and the largest
/// rise `I(s + n̂) - I(s - n̂)` of the search (`rise`, grey levels: how strong the edge is).
#[derive(Debug, Clone, Copy)]
pub(crate) struct EdgePoint {
    pub(crate) offset: f32,
    pub(crate) rise: f32,
}

/// The edge point across `(x0, y0)` along `(nx, ny)`, searched over `±(decimate + 1)` px
/// (module docs); `None` where the intensity never rises outward (or the samples are outside
/// the image).
pub(crate) fn edge_point(
    img: &ImageView<'_, u8>,
    x0: f32,
    y0: f32,
    nx: f32,
    ny: f32,
    decimate: usize,
) -> Option<EdgePoint> {
    let range = decimate as f32 + 1.0;
    let steps = 2 * 4 * (decimate + 1) + 1;
    let (mut mn, mut mc, mut rise) = (0f32, 0f32, 0f32);
    // The samples along the normal, 1/4 px apart from `-range - 1` to `range + 1` (NaN outside
    // the image): step k compares the one at `n + 1` (index k + 8) with the one at `n - 1`
    // (index k), so each is read once, not twice. The offsets are multiples of 1/4 below
    // 2^24, exact in f32, so the positions are bit for bit those of AprilTag's two reads.
    let (data, stride) = (img.data(), img.stride());
    let (xmax, ymax) = (
        img.width().saturating_sub(1) as f32,
        img.height().saturating_sub(1) as f32,
    );
    let inside = |x: f32, y: f32| x >= 0.0 && y >= 0.0 && x <= xmax && y <= ymax;
    let at = |j: usize| {
        let m = -range - 1.0 + 0.25 * j as f32;
        (x0 + m * nx, y0 + m * ny)
    };
    // The positions are monotone in j (each step of the computation rounds monotonically),
    // so when both ends are inside the image, every sample is.
    let ((xa, ya), (xb, yb)) = (at(0), at(steps + 7));
    let all_inside = inside(xa, ya) && inside(xb, yb);
    // Step k needs the samples k and k + 8 only: the last eight samples in a ring (not all
    // of them in an array, whose NaN fill cost more than the steps), the first eight read
    // first, then each step done as its second sample arrives; the same samples and the
    // same sums in the same order.
    let sample = |j: usize| {
        let (x, y) = at(j);
        if all_inside || inside(x, y) {
            bilinear(data, stride, x, y)
        } else {
            f32::NAN
        }
    };
    let total = (steps + 8).min(MAX_ALONG);
    let mut ring: [f32; 8] = core::array::from_fn(|j| if j < total { sample(j) } else { f32::NAN });
    for j in 8..total {
        let g1 = sample(j);
        let g2 = ring
            .get_mut(j % 8)
            .map_or(f32::NAN, |slot| core::mem::replace(slot, g1));
        let n = -range + 0.25 * (j - 8) as f32;
        // NaN (outside) fails the comparison too.
        if !at_most(g2, g1) {
            continue;
        }
        let w = (g2 - g1) * (g2 - g1);
        mn += w * n;
        mc += w;
        rise = rise.max(g1 - g2);
    }
    if !above(mc, 0.0) {
        return None;
    }
    Some(EdgePoint {
        offset: mn / mc,
        rise,
    })
}

/// [`ImageView::sample_bilinear`] on the view's bytes (`data`, `stride`) at `(x, y)` inside
/// the image, the same arithmetic in the same order (so the same value to the bit): the edge
/// points' inner loop, without the row look-ups. The right and lower neighbours are read even
/// where `a` or `b` is 0 (where the view reads the pixel itself): their terms are then
/// `0 · p = +0` for any pixel value, and adding `+0` to the non-negative sum changes nothing.
#[inline(always)]
fn bilinear(data: &[u8], stride: usize, x: f32, y: f32) -> f32 {
    // Inside and non-negative: truncation is the floor.
    let (i, j) = (x as usize, y as usize);
    let (a, b) = (x - i as f32, y - j as f32);
    let k = j * stride + i;
    // A pixel and its right neighbour from one bounds check; past the end of the data the
    // neighbour (whose weight is then 0) reads 0.
    let two = |k: usize| match data.get(k..k.wrapping_add(2)) {
        Some(&[l, r]) => (f32::from(l), f32::from(r)),
        _ => (f32::from(data.get(k).copied().unwrap_or(0)), 0.0),
    };
    // Inside the image the four pixels are in the `stride + 2` bytes from `k`: one bounds
    // check for the window (the pairs in it need none), the pairs one by one otherwise.
    let window = data
        .get(k..)
        .and_then(|d| d.get(..stride.wrapping_add(2)))
        .and_then(|w| Some((w.first_chunk::<2>()?, w.get(stride..)?.first_chunk::<2>()?)));
    let ((p00, p10), (p01, p11)) = match window {
        Some((&[l0, r0], &[l1, r1])) => (
            (f32::from(l0), f32::from(r0)),
            (f32::from(l1), f32::from(r1)),
        ),
        None => (two(k), two(k + stride)),
    };
    (1.0 - a) * (1.0 - b) * p00 + a * (1.0 - b) * p10 + (1.0 - a) * b * p01 + a * b * p11
}

/// Least-squares plane `I = c₀ x + c₁ y + c₂` over tag coordinates.
#[derive(Default, Clone, Copy)]
pub(crate) struct GrayModel {
    a: [f32; 6], // xx, xy, x, yy, y, n
    b: [f32; 3],
    c: [f32; 3],
}

impl GrayModel {
    pub(crate) fn add(&mut self, x: f32, y: f32, g: f32) {
        let a = &mut self.a;
        a[0] += x * x;
        a[1] += x * y;
        a[2] += x;
        a[3] += y * y;
        a[4] += y;
        a[5] += 1.0;
        self.b[0] += x * g;
        self.b[1] += y * g;
        self.b[2] += g;
    }

    /// Cholesky solve; `false` when the normal matrix is not positive definite.
    pub(crate) fn solve(&mut self) -> bool {
        let [a00, a01, a02, a11, a12, a22] = self.a;
        let l00 = a00;
        if !above(l00, 0.0) {
            return false;
        }
        let l00 = libm::sqrtf(l00);
        let l10 = a01 / l00;
        let l20 = a02 / l00;
        let d1 = a11 - l10 * l10;
        if !above(d1, 0.0) {
            return false;
        }
        let l11 = libm::sqrtf(d1);
        let l21 = (a12 - l20 * l10) / l11;
        let d2 = a22 - l20 * l20 - l21 * l21;
        if !above(d2, 0.0) {
            return false;
        }
        let l22 = libm::sqrtf(d2);
        let [b0, b1, b2] = self.b;
        let y0 = b0 / l00;
        let y1 = (b1 - l10 * y0) / l11;
        let y2 = (b2 - l20 * y0 - l21 * y1) / l22;
        let c2 = y2 / l22;
        let c1 = (y1 - l21 * c2) / l11;
        let c0 = (y0 - l10 * c1 - l20 * c2) / l00;
        self.c = [c0, c1, c2];
        c0.is_finite() && c1.is_finite() && c2.is_finite()
    }

    #[inline]
    pub(crate) fn at(&self, x: f32, y: f32) -> f32 {
        self.c[0] * x + self.c[1] * y + self.c[2]
    }
}

/// Largest `total_width` the decoder's cell grid holds.
pub const MAX_TOTAL_WIDTH: usize = 12;

/// A read payload: the word, the decision margin, whether every sample of the ring just
/// outside the detection border (the quiet zone) was inside the image, the border cells read
/// white (ArUco dictionaries: the border ring, OpenCV's `_getBorderErrors`; a family with a
/// border wider than one cell: its inner rings; 0 otherwise), and the contrast of the quiet
/// zone over the border at the centre (the two models' difference, grey levels).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Reading {
    pub(crate) rcode: u64,
    pub(crate) margin: f32,
    pub(crate) ring_in_view: bool,
    pub(crate) border_errors: u16,
    pub(crate) contrast: f32,
}

/// The detector's sample rows of the quiet zone (white) and the border (black), `(x0, y0, dx,
/// dy, white)` in cells from the border's outer corner, for a border `wab` cells wide: the
/// intensity models' samples ([`read_code`] and the partial view's reading).
pub(crate) fn border_rows(wab: f32) -> [(f32, f32, f32, f32, bool); 8] {
    [
        (-0.5, 0.5, 0.0, 1.0, true),
        (0.5, 0.5, 0.0, 1.0, false),
        (wab + 0.5, 0.5, 0.0, 1.0, true),
        (wab - 0.5, 0.5, 0.0, 1.0, false),
        (0.5, -0.5, 1.0, 0.0, true),
        (0.5, 0.5, 1.0, 0.0, false),
        (0.5, wab + 0.5, 1.0, 0.0, true),
        (0.5, wab - 0.5, 1.0, 0.0, false),
    ]
}

/// Sharpens a `tw x tw` grid of cell values (row-major) with AprilTag's `decode_sharpening`:
/// `v += k (4 v - v_left - v_right - v_up - v_down)`, the discrete Laplacian of the values
/// before any change (cells beyond the grid count as 0), on the cells `keep` selects; no change
/// when `k = 0`.
pub(crate) fn sharpen(
    values: &mut [f32; MAX_TOTAL_WIDTH * MAX_TOTAL_WIDTH],
    tw: usize,
    sharpening: f32,
    keep: impl Fn(usize) -> bool,
) {
    if sharpening == 0.0 {
        return;
    }
    let orig = *values;
    for y in 0..tw {
        for x in 0..tw {
            if !keep(y * tw + x) {
                continue;
            }
            let at = |xx: usize, yy: usize| orig.get(yy * tw + xx).copied().unwrap_or(0.0);
            let mut s = 4.0 * at(x, y);
            if x > 0 {
                s -= at(x - 1, y);
            }
            if x + 1 < tw {
                s -= at(x + 1, y);
            }
            if y > 0 {
                s -= at(x, y - 1);
            }
            if y + 1 < tw {
                s -= at(x, y + 1);
            }
            if let Some(v) = values.get_mut(y * tw + x) {
                *v += sharpening * s;
            }
        }
    }
}

/// Reads the payload of the quad `h` maps to (module docs), `None` when the border does not
/// fit the family (wrong polarity, or too few border samples inside the image for the
/// intensity models).
pub(crate) fn read_code(
    img: &ImageView<'_, u8>,
    h: &Matrix3<f32>,
    family: &Family,
    sharpening: f32,
) -> Option<Reading> {
    let wab = usize::from(family.width_at_border);
    let wabf = wab as f32;
    let tw = usize::from(family.total_width);
    if tw > MAX_TOTAL_WIDTH || wab < 2 {
        return None;
    }
    let patterns = border_rows(wabf);
    let (mut white, mut black) = (GrayModel::default(), GrayModel::default());
    let (w, hgt) = (img.width() as f32, img.height() as f32);
    let mut ring_in_view = true;
    for &(x0, y0, dx, dy, is_white) in &patterns {
        for i in 0..wab {
            let tx = 2.0 * ((x0 + i as f32 * dx) / wabf - 0.5);
            let ty = 2.0 * ((y0 + i as f32 * dy) / wabf - 0.5);
            let Some(p) = project(h, tx, ty) else {
                ring_in_view &= !is_white;
                continue;
            };
            // AprilTag truncates its coordinate: the pixel containing the point.
            let (ix, iy) = (p.x + 0.5, p.y + 0.5);
            if !(ix >= 0.0 && iy >= 0.0 && ix < w && iy < hgt) {
                ring_in_view &= !is_white;
                continue;
            }
            let v = f32::from(img.get(ix as usize, iy as usize).unwrap_or(0));
            if is_white {
                white.add(tx, ty, v);
            } else {
                black.add(tx, ty, v);
            }
        }
    }
    if !white.solve() || !black.solve() {
        return None;
    }
    if (white.at(0.0, 0.0) - black.at(0.0, 0.0) < 0.0) != family.reversed_border {
        return None;
    }
    let min_coord = (wab as i32 - tw as i32) / 2;
    let mut values = [0f32; MAX_TOTAL_WIDTH * MAX_TOTAL_WIDTH];
    let cell = |x: i32, y: i32| -> Option<usize> {
        let (cx, cy) = (x - min_coord, y - min_coord);
        if cx < 0 || cy < 0 || cx >= tw as i32 || cy >= tw as i32 {
            return None;
        }
        Some(cy as usize * tw + cx as usize)
    };
    let read = |x: i32, y: i32, values: &mut [f32; MAX_TOTAL_WIDTH * MAX_TOTAL_WIDTH]| {
        let tx = 2.0 * ((x as f32 + 0.5) / wabf - 0.5);
        let ty = 2.0 * ((y as f32 + 0.5) / wabf - 0.5);
        let Some(p) = project(h, tx, ty) else {
            return;
        };
        let Some(v) = img.sample_bilinear(p.x, p.y) else {
            return;
        };
        let thresh = 0.5 * (black.at(tx, ty) + white.at(tx, ty));
        if let Some(slot) = cell(x, y).and_then(|i| values.get_mut(i)) {
            *slot = v - thresh;
        }
    };
    // The payload cells, the layout moved inward for a border wider than one cell.
    let bits = || (0..family.layout.len()).filter_map(|i| family.bit_cell(i));
    for (x, y) in bits() {
        read(x, y, &mut values);
    }
    // The border ring of an ArUco marker: cells (x, y) of 0..wab with x or y at 0 or wab - 1.
    let aruco = family.is_aruco();
    // The ring of cells `d` in from the border's outer edge: (x, y) of d..wab - d with x or
    // y at d or wab - 1 - d.
    let rings = move |d: i32| {
        let (lo, hi) = (d, wab as i32 - 1 - d);
        (lo..=hi).flat_map(move |i| {
            let side = [(i, lo), (i, hi)];
            let inner = (lo + 1..hi).contains(&i).then_some([(lo, i), (hi, i)]);
            side.into_iter().chain(inner.into_iter().flatten())
        })
    };
    let ring = move || rings(0);
    if aruco {
        for (x, y) in ring() {
            read(x, y, &mut values);
        }
    }
    sharpen(&mut values, tw, sharpening, |_| true);
    let (mut ws, mut bs, mut wc, mut bc) = (0f32, 0f32, 1f32, 1f32);
    let mut rcode: u64 = 0;
    for (x, y) in bits() {
        let v = cell(x, y)
            .and_then(|i| values.get(i))
            .copied()
            .unwrap_or(0.0);
        rcode <<= 1;
        if v > 0.0 {
            ws += v;
            wc += 1.0;
            rcode |= 1;
        } else {
            bs -= v;
            bc += 1.0;
        }
    }
    let border_errors = if aruco {
        // OpenCV thresholds a marker's cells by Otsu over the marker itself (border and
        // payload), not against its surround: one step of two-means from the models' split
        // does the same, `t = (mean of the cells above 0 + mean of those at or below) / 2`.
        // A real marker's cells sit near its two levels and `t` stays near 0; a patch of
        // texture inside a bright surround has its split moved down, and its border cells
        // no longer all read black.
        let at = |(x, y): (i32, i32)| cell(x, y).and_then(|i| values.get(i)).copied();
        let cells = bits().chain(ring()).filter_map(at);
        let (mut hi, mut nhi, mut lo, mut nlo) = (0f32, 0u32, 0f32, 0u32);
        for v in cells {
            if v > 0.0 {
                hi += v;
                nhi += 1;
            } else {
                lo += v;
                nlo += 1;
            }
        }
        let t = if nhi > 0 && nlo > 0 {
            0.5 * (hi / nhi as f32 + lo / nlo as f32)
        } else {
            0.0
        };
        ring().filter(|&c| at(c).is_some_and(|v| v > t)).count() as u16
    } else {
        // A border wider than a cell: the rings inside the outer one, read after the payload
        // (which is read as for a 1-cell border) against the models' threshold; a cell read
        // white is a wrong bit of the tag.
        let mut wrong = 0u16;
        for d in 1..i32::from(family.border_bits) {
            for (x, y) in rings(d) {
                read(x, y, &mut values);
                let v = cell(x, y).and_then(|i| values.get(i)).copied();
                wrong += u16::from(v.is_some_and(|v| v > 0.0));
            }
        }
        wrong
    };
    Some(Reading {
        rcode,
        margin: (ws / wc).min(bs / bc),
        ring_in_view,
        border_errors,
        contrast: white.at(0.0, 0.0) - black.at(0.0, 0.0),
    })
}
