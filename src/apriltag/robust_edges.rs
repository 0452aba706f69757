//! A robust fit of a quad's edges: the edge refinement for a tag partly hidden (an occluder
//! across an edge) or cut by the frame's edge, where the plain fit ([`super::decode`]) averages
//! points that are not on the tag's edge.
//!
//! Each edge is sampled at `n` positions (`len / 8` of them as the plain refinement, at least
//! the caller's minimum, at most [`MAX_SAMPLES`]), each searched across the edge as the detector's refinement does
//! ([`edge_point`]: where the intensity rises outward, and by how much). A position gives
//! nothing when its search reaches outside the frame ([`Sample::Outside`]); an edge point whose rise is
//! below half the median rise of the quad's points is not the tag's edge (an occluder darker
//! than the quiet zone, or one brighter than the border, leaves a weak step, a few grey
//! levels where the tag's edge has the ink-to-paper contrast). The line is then fitted to the
//! others by consensus: every pair of points half and a quarter of the edge's points apart
//! is a hypothesis, scored by MSAC (`Σ min(r², τ²)`, `τ` = [`INLIER_PX`]); the
//! best one's inliers (`|r| ≤ τ`) get a least-squares line (the covariance's eigenvector, as
//! the plain fit), whose inliers get it again. Consecutive lines are intersected into the
//! corners, so a corner outside the frame or under an occluder is where its two edges meet.
//!
//! Each edge tells how it was measured ([`EdgeSupport`]): its inliers, the share of the edge
//! they span, and the part of the edge in the frame that gave no inlier (what hides the tag
//! there), which the reading of the code leaves out ([`super::visible_code`]).
//!
//! Work: `4 n` edge points (33 to 41 bilinear samples each), the median by a histogram of whole grey levels and
//! at most `4 · 1.25 n` hypotheses of `n` residuals.

use nalgebra::Point2;

use super::decode::{EdgePoint, edge_point};
use super::geom::{Line, LineMoments, at4, intersect};
use super::quad::Quad;
use crate::image::ImageView;
use crate::scalar::above;

/// Sample positions on an edge, at most.
pub(crate) const MAX_SAMPLES: usize = 48;

/// An edge point whose rise is below this share of the median rise of the quad's points is not
/// on the tag's edge.
const WEAK: f32 = 0.5;

/// Largest distance of an inlier from its line, pixels: three times the scatter of a seen
/// edge's points about their line (within 0.1 px rms: mean squared 0.009 px² at most on the
/// rendered sequence, BENCHMARKS "the tag job"); what an occluder's edge or blur displaces
/// lies further.
pub(crate) const INLIER_PX: f32 = 0.3;

/// Bisections of each end of an edge's hidden part (each one edge point).
const BISECTIONS: usize = 2;

/// What one sample position on an edge gave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Sample {
    /// Outside the frame.
    Outside,
    /// In the frame, but no point of the tag's edge: none found, too weak or off the line.
    Hidden,
    /// An inlier of the edge's line.
    Seen,
}

/// How one edge of [`robust_edges`] was measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct EdgeSupport {
    /// Sample positions.
    pub(crate) samples: u8,
    /// Inliers of the line.
    pub(crate) inliers: u8,
    /// The share of the edge (0..1) from its first inlier to its last.
    pub(crate) span: f32,
    /// Mean squared distance of the inliers from the line (px²).
    pub(crate) mse: f32,
    /// The part of the edge in the frame that gave no inlier, as fractions `(t0, t1)` of the
    /// edge from its first corner (widened to the neighbouring positions that did, or to the
    /// corners): `None` when every position in the frame gave one.
    pub(crate) hidden: Option<(f32, f32)>,
}

impl EdgeSupport {
    /// An edge that was not measured.
    const NONE: Self = Self {
        samples: 0,
        inliers: 0,
        span: 0.0,
        mse: 0.0,
        hidden: None,
    };
}

/// An edge point relative to its edge's midpoint, its rise and where on the edge it was
/// looked for (fraction from the first corner).
#[derive(Debug, Clone, Copy, Default)]
struct Point {
    x: f32,
    y: f32,
    rise: f32,
    t: f32,
}

/// One edge's samples.
struct Edge {
    line: Line,
    /// The edge's corners as sampled.
    a: Point2<f32>,
    b: Point2<f32>,
    n: usize,
    status: [Sample; MAX_SAMPLES],
    points: [Point; MAX_SAMPLES],
    /// Whether `points[k]` holds an edge point.
    found: [bool; MAX_SAMPLES],
}

impl Edge {
    const EMPTY: Self = Self {
        line: Line::ZERO,
        a: Point2::new(0.0, 0.0),
        b: Point2::new(0.0, 0.0),
        n: 0,
        status: [Sample::Outside; MAX_SAMPLES],
        points: [Point {
            x: 0.0,
            y: 0.0,
            rise: 0.0,
            t: 0.0,
        }; MAX_SAMPLES],
        found: [false; MAX_SAMPLES],
    };
}

/// One robust refinement pass over the edges of `q` (module docs): the search across
/// `±(decimate + 1)` px, at least `min_points` positions an edge; with `bisect`, the ends of
/// each edge's hidden part located between its positions (only the support of the last pass
/// is used). The corners move to the intersections of the fitted lines (a corner whose lines
/// do not meet stays). Returns how each edge (`q.p[i]` to `q.p[i + 1]`) was measured.
pub(crate) fn robust_edges(
    img: &ImageView<'_, u8>,
    q: &mut Quad,
    decimate: usize,
    min_points: usize,
    bisect: bool,
) -> [EdgeSupport; 4] {
    let mut edges = [Edge::EMPTY, Edge::EMPTY, Edge::EMPTY, Edge::EMPTY];
    let longest = (img.width() + img.height()) as f32;
    // The rises in whole grey levels, for their median.
    let mut rises = [0u16; 256];
    let mut nrises = 0u32;
    for (i, e) in edges.iter_mut().enumerate() {
        let (pa, pb) = (at4(&q.p, i), at4(&q.p, i + 1));
        let (mut nx, mut ny) = (pb.y - pa.y, -(pb.x - pa.x));
        let mag = libm::sqrtf(nx * nx + ny * ny);
        if !above(mag, 0.0) || !mag.is_finite() {
            continue;
        }
        nx /= mag;
        ny /= mag;
        if q.reversed_border {
            nx = -nx;
            ny = -ny;
        }
        let (mx, my) = (0.5 * (pa.x + pb.x), 0.5 * (pa.y + pb.y));
        (e.a, e.b) = (pa, pb);
        e.line = Line {
            ex: mx,
            ey: my,
            nx,
            ny,
        };
        // As the plain refinement: a predicted edge can be any length, one in the frame is
        // shorter than its width plus height.
        e.n = ((mag.min(longest) / 8.0) as usize)
            .max(min_points)
            .min(MAX_SAMPLES);
        for k in 0..e.n {
            let t = (1.0 + k as f32) / (e.n as f32 + 1.0);
            let (x0, y0) = (pa.x + t * (pb.x - pa.x), pa.y + t * (pb.y - pa.y));
            let (Some(status), Some(point), Some(found)) =
                (e.status.get_mut(k), e.points.get_mut(k), e.found.get_mut(k))
            else {
                break;
            };
            if !searchable(img, x0, y0, nx, ny, decimate) {
                *status = Sample::Outside;
                continue;
            }
            *status = Sample::Hidden;
            if let Some(EdgePoint { offset, rise }) = edge_point(img, x0, y0, nx, ny, decimate) {
                *point = Point {
                    x: x0 + offset * nx - mx,
                    y: y0 + offset * ny - my,
                    rise,
                    t,
                };
                *found = true;
                if let Some(r) = rises.get_mut(rise.clamp(0.0, 255.0) as usize) {
                    *r += 1;
                    nrises += 1;
                }
            }
        }
    }
    let mut support = [EdgeSupport::NONE; 4];
    if nrises == 0 {
        return support;
    }
    let (mut below, mut median) = (0u32, 0f32);
    for (level, &n) in rises.iter().enumerate() {
        below += u32::from(n);
        if 2 * below >= nrises {
            median = level as f32;
            break;
        }
    }
    let weak = WEAK * median;
    let mut lines = [Line::ZERO; 4];
    for ((e, s), line) in edges
        .iter_mut()
        .zip(support.iter_mut())
        .zip(lines.iter_mut())
    {
        *line = e.line;
        s.samples = e.n as u8;
        for (f, p) in e.found.iter_mut().zip(e.points.iter()).take(e.n) {
            if *f && !at_least(p.rise, weak) {
                *f = false;
            }
        }
        if let Some((fit, mse)) = consensus(e) {
            *line = Line {
                ex: fit.ex + e.line.ex,
                ey: fit.ey + e.line.ey,
                nx: fit.nx,
                ny: fit.ny,
            };
            s.mse = mse;
        }
        let fitted = *line;
        let (mut first, mut last, mut inliers) = (f32::INFINITY, f32::NEG_INFINITY, 0u8);
        let (mut h0, mut h1) = (None::<usize>, None::<usize>);
        for k in 0..e.n {
            match e.status.get(k) {
                Some(Sample::Seen) => {
                    let t = e.points.get(k).map_or(0.0, |p| p.t);
                    first = first.min(t);
                    last = last.max(t);
                    inliers = inliers.saturating_add(1);
                }
                Some(Sample::Hidden) => {
                    h0 = h0.or(Some(k));
                    h1 = Some(k);
                }
                _ => {}
            }
        }
        s.inliers = inliers;
        s.span = if inliers > 0 { last - first } else { 0.0 };
        let nf = e.n as f32 + 1.0;
        // Whether the edge is seen at `t`: an edge point there, strong enough, on the line.
        let seen_at = |t: f32| {
            let (x0, y0) = (e.a.x + t * (e.b.x - e.a.x), e.a.y + t * (e.b.y - e.a.y));
            let (nx, ny) = (e.line.nx, e.line.ny);
            if !searchable(img, x0, y0, nx, ny, decimate) {
                return false;
            }
            edge_point(img, x0, y0, nx, ny, decimate).is_some_and(|p| {
                let q = Point {
                    x: x0 + p.offset * nx,
                    y: y0 + p.offset * ny,
                    rise: p.rise,
                    t,
                };
                at_least(p.rise, weak) && distance(&fitted, &q) <= INLIER_PX
            })
        };
        s.hidden = match (h0, h1) {
            // Between the position before the first hidden one and the one after the last,
            // each end bisected twice toward where the edge is seen: the hidden part known to
            // a quarter of the positions' spacing, and never less than the positions hidden.
            (Some(a), Some(b)) if inliers > 0 && bisect => {
                let (mut lo, mut hi) = (a as f32 / nf, (a + 1) as f32 / nf);
                for _ in 0..BISECTIONS {
                    let mid = 0.5 * (lo + hi);
                    if seen_at(mid) { lo = mid } else { hi = mid }
                }
                let t0 = lo;
                let (mut lo, mut hi) = ((b + 1) as f32 / nf, ((b + 2) as f32 / nf).min(1.0));
                for _ in 0..BISECTIONS {
                    let mid = 0.5 * (lo + hi);
                    if seen_at(mid) { hi = mid } else { lo = mid }
                }
                Some((t0, hi))
            }
            (Some(a), Some(b)) => Some((a as f32 / nf, ((b + 2) as f32 / nf).min(1.0))),
            _ => None,
        };
    }
    let old = q.p;
    for (i, p) in q.p.iter_mut().enumerate() {
        *p = intersect(&at4(&lines, i + 3), &at4(&lines, i)).unwrap_or(at4(&old, i));
    }
    support
}

/// Whether the search across the edge at `(x0, y0)` along `(nx, ny)` lies in the frame: it
/// runs `decimate + 2` px either side, and cut by the frame's edge it measures nothing of the
/// tag.
fn searchable(
    img: &ImageView<'_, u8>,
    x0: f32,
    y0: f32,
    nx: f32,
    ny: f32,
    decimate: usize,
) -> bool {
    let (xmax, ymax) = (img.width() as f32 - 1.0, img.height() as f32 - 1.0);
    let reach = decimate as f32 + 2.0;
    let inside = |x: f32, y: f32| x >= 0.0 && y >= 0.0 && x <= xmax && y <= ymax;
    let (ox, oy) = (reach * nx, reach * ny);
    inside(x0 - ox, y0 - oy) && inside(x0 + ox, y0 + oy)
}

/// The share (0..1) of the segment `a`-`b` whose points lie at least `margin` px inside a
/// `width x height` frame (pixel centres `0..width - 1`): Liang-Barsky clipping. 0 for a
/// segment that is not finite.
pub(crate) fn share_in_frame(
    a: Point2<f32>,
    b: Point2<f32>,
    width: usize,
    height: usize,
    margin: f32,
) -> f32 {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let (lo_x, hi_x) = (margin, width as f32 - 1.0 - margin);
    let (lo_y, hi_y) = (margin, height as f32 - 1.0 - margin);
    let (mut t0, mut t1) = (0.0f32, 1.0f32);
    // Each side: p t ≤ q keeps the point inside.
    for (p, q) in [
        (-dx, a.x - lo_x),
        (dx, hi_x - a.x),
        (-dy, a.y - lo_y),
        (dy, hi_y - a.y),
    ] {
        if !(p.is_finite() && q.is_finite()) {
            return 0.0;
        }
        if p == 0.0 {
            if q < 0.0 {
                return 0.0;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    (t1 - t0).max(0.0)
}

/// `a ≥ b`, false for NaN.
fn at_least(a: f32, b: f32) -> bool {
    a >= b
}

/// The consensus line of an edge's points that are found (module docs), relative to its
/// midpoint, and the inliers' mean squared distance; marks each position [`Sample::Seen`] (an
/// inlier) or leaves it [`Sample::Hidden`] / [`Sample::Outside`]. `None` with fewer than two
/// points or no line through them.
fn consensus(e: &mut Edge) -> Option<(Line, f32)> {
    // The found points, contiguous, and where each came from.
    let mut idx = [0u8; MAX_SAMPLES];
    let mut xy = [(0f32, 0f32); MAX_SAMPLES];
    let mut c = 0usize;
    for (k, (f, p)) in e.found.iter().zip(e.points.iter()).enumerate().take(e.n) {
        if *f && let (Some(slot), Some(q)) = (idx.get_mut(c), xy.get_mut(c)) {
            *slot = k as u8;
            *q = (p.x, p.y);
            c += 1;
        }
    }
    let xy = xy.get(..c).unwrap_or(&[]);
    if c < 2 {
        return None;
    }
    let tau2 = INLIER_PX * INLIER_PX;
    let mut best: Option<(f32, Line)> = None;
    let gaps = [(c / 2).max(1), (c / 4).max(1)];
    for (gi, &g) in gaps.iter().enumerate() {
        if gi > 0 && gaps.first() == Some(&g) {
            continue;
        }
        for (&(ax, ay), &(bx, by)) in xy.iter().zip(xy.iter().skip(g)) {
            let (dx, dy) = (bx - ax, by - ay);
            let len = libm::sqrtf(dx * dx + dy * dy);
            if !above(len, 0.0) {
                continue;
            }
            let (nx, ny) = (-dy / len, dx / len);
            let mut cost = 0f32;
            for &(x, y) in xy {
                let r = (x - ax) * nx + (y - ay) * ny;
                cost += (r * r).min(tau2);
            }
            if best.as_ref().is_none_or(|(b, _)| cost < *b) {
                best = Some((
                    cost,
                    Line {
                        ex: ax,
                        ey: ay,
                        nx,
                        ny,
                    },
                ));
            }
        }
    }
    let pts = &e.points;
    let at = |j: usize| -> Point {
        idx.get(j)
            .and_then(|&k| pts.get(usize::from(k)))
            .copied()
            .unwrap_or_default()
    };
    let (_, mut line) = best?;
    let mut mse = 0.0;
    // Least squares on the inliers, twice (the second on the first's inliers).
    for _ in 0..2 {
        // The points are relative to the edge's midpoint already (small numbers for f32).
        let mut m = LineMoments::new(0.0, 0.0);
        for j in 0..c {
            let p = at(j);
            if distance(&line, &p) <= INLIER_PX {
                m.add(p.x, p.y);
            }
        }
        let Some((fitted, small)) = m.fit() else {
            break;
        };
        line = fitted;
        mse = small;
    }
    for j in 0..c {
        let p = at(j);
        let seen = distance(&line, &p) <= INLIER_PX;
        if let Some(&k) = idx.get(j)
            && let Some(s) = e.status.get_mut(usize::from(k))
        {
            *s = if seen { Sample::Seen } else { Sample::Hidden };
        }
    }
    Some((line, mse))
}

/// Distance of `p` from `line` (its normal a unit vector).
fn distance(line: &Line, p: &Point) -> f32 {
    ((p.x - line.ex) * line.nx + (p.y - line.ey) * line.ny).abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_share_in_the_frame_is_the_clipped_segment() {
        let p = |x, y| Point2::new(x, y);
        assert_eq!(
            share_in_frame(p(10.0, 10.0), p(20.0, 10.0), 320, 240, 3.0),
            1.0
        );
        // From x = 300 to 340, inside up to 319 - 3 = 316: 16 of 40.
        let s = share_in_frame(p(300.0, 50.0), p(340.0, 50.0), 320, 240, 3.0);
        assert!((s - 0.4).abs() < 1e-6, "{s}");
        assert_eq!(
            share_in_frame(p(330.0, 50.0), p(340.0, 60.0), 320, 240, 3.0),
            0.0
        );
        assert_eq!(
            share_in_frame(p(f32::NAN, 50.0), p(40.0, 60.0), 320, 240, 3.0),
            0.0
        );
    }

    /// A consensus fit keeps the points on the line and drops a run that is off it.
    #[test]
    fn consensus_drops_a_displaced_run() {
        let mut e = Edge::EMPTY;
        e.n = 30;
        for k in 0..30 {
            let t = (k as f32 + 1.0) / 31.0;
            // The line y = 0.1 x + 0.3 over x in -15..15; positions 10..16 pushed 2 px off.
            let x = -15.0 + 30.0 * t;
            let off = if (10..17).contains(&k) { 2.0 } else { 0.0 };
            e.points[k] = Point {
                x,
                y: 0.1 * x + 0.3 + off,
                rise: 100.0,
                t,
            };
            e.found[k] = true;
            e.status[k] = Sample::Hidden;
        }
        let (line, mse) = consensus(&mut e).unwrap();
        assert!(mse < 1e-6, "{mse}");
        let seen = e
            .status
            .iter()
            .take(30)
            .filter(|s| **s == Sample::Seen)
            .count();
        assert_eq!(seen, 23);
        // The normal is that of y = 0.1 x + 0.3, through (0, 0.3).
        let d = ((0.0 - line.ex) * line.nx + (0.3 - line.ey) * line.ny).abs();
        assert!(
            d < 1e-4 && (line.nx / line.ny + 0.1).abs() < 1e-4,
            "{line:?}"
        );
    }
}
