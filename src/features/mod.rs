//! Image features: FAST corners, ORB descriptors, SIFT keypoints with float descriptors, and
//! brute-force matching (Hamming or Euclidean).
//!
//! Everything here is allocation-free: detectors write into fixed-capacity
//! [`heapless::Vec`]s or caller slices and take their working memory as one caller-provided
//! byte slice whose length a `const fn` gives ([`fast::scratch_len`], [`orb::scratch_len`],
//! [`matching::scratch_len`]; SIFT's in `f32`s, [`sift::scratch_len`]). The work of every function is bounded by the image size and
//! the capacities (stated per function).
//!
//! | module | what |
//! |---|---|
//! | [`fast`] | FAST-9 corners on the 16-pixel Bresenham circle with 3x3 non-maximum suppression, integer Harris response |
//! | [`orb`] | ORB: multi-scale FAST + Harris selection (optionally spread by a grid), intensity-centroid orientation, steered 256-bit BRIEF, optional sub-pixel positions |
//! | [`sift`] | SIFT: difference-of-Gaussian extrema in a scale space, sub-pixel and sub-scale refinement, orientation histograms, 128-float descriptors (RootSIFT optional) |
//! | [`matching`] | Hamming or Euclidean distance, brute-force matching with Lowe's ratio test and cross-check, optionally among the pairs a geometry admits (guided) |
//!
//! ORB features of a drawn scene and of the same scene moved by `(+5, +3)` pixels, matched:
//!
//! ```
//! use camgeom::features::{Feature, Match, MatchParams, OrbConfig};
//! use camgeom::features::{match_descriptors, orb, orb_detect};
//! use camgeom::heapless::Vec;
//! use camgeom::image::ImageView;
//!
//! // `scene(dx, dy)`: a 112x112 frame of overlapping grey rectangles (blurred by a 3x3 box)
//! // moved by (dx, dy).
//! # let rects = [(18, 20, 34, 40, 200), (30, 34, 52, 48, 90), (50, 18, 70, 30, 160),
//! #     (58, 40, 78, 62, 220), (22, 52, 44, 70, 140), (46, 60, 60, 78, 60)];
//! # let rect = |x: usize, y: usize| -> u32 {
//! #     let inside = |&&(x0, y0, x1, y1, _): &&(usize, usize, usize, usize, u32)| {
//! #         (x0..x1).contains(&x) && (y0..y1).contains(&y)
//! #     };
//! #     rects.iter().rev().find(inside).map_or(30, |r| r.4)
//! # };
//! # let scene = |dx: usize, dy: usize| -> [u8; 112 * 112] {
//! #     core::array::from_fn(|i| {
//! #         let (x, y) = ((i % 112).wrapping_sub(dx + 1), (i / 112).wrapping_sub(dy + 1));
//! #         let s: u32 = (0..9).map(|k| rect(x.wrapping_add(k % 3), y.wrapping_add(k / 3))).sum();
//! #         (s / 9) as u8
//! #     })
//! # };
//! let (a, b) = (scene(0, 0), scene(5, 3));
//! let params = OrbConfig { levels: 1, ..OrbConfig::default() }.check()?;
//! let mut scratch = [0u8; orb::scratch_len(112, 112, 307)];
//! let (mut fa, mut fb) = (Vec::<Feature, 64>::new(), Vec::<Feature, 64>::new());
//! orb_detect(&ImageView::packed(&a, 112, 112)?, &params, &mut scratch, &mut fa)?;
//! orb_detect(&ImageView::packed(&b, 112, 112)?, &params, &mut scratch, &mut fb)?;
//! let da: Vec<_, 64> = fa.iter().map(|f| f.descriptor).collect();
//! let db: Vec<_, 64> = fb.iter().map(|f| f.descriptor).collect();
//! let (mut matches, mut ms) = ([Match::default(); 64], [0u32; 64]);
//! let n = match_descriptors(&da, &db, &MatchParams::default(), &mut ms, &mut matches)?;
//! // Most features match (the ratio test drops corners congruent to another one), and every
//! // match is the feature itself, moved by the shift.
//! assert!(fa.len() >= 16 && n >= fa.len() * 3 / 4);
//! for m in &matches[..n] {
//!     let (p, q) = (fa[m.query as usize].keypoint, fb[m.train as usize].keypoint);
//!     assert_eq!((q.x - p.x, q.y - p.y, m.distance), (5.0, 3.0, 0));
//! }
//! # Ok::<(), camgeom::Error>(())
//! ```

pub mod fast;
pub mod matching;
pub mod orb;
pub mod sift;

pub use fast::{Corner, FastConfig, FastParams, fast_detect, harris_response};
pub use matching::{
    Descriptor, FloatDescriptor, FloatMatch, Match, MatchConfig, MatchParams, hamming, l2_squared,
    match_descriptors, match_descriptors_guided, match_float_descriptors,
    match_float_descriptors_guided,
};
pub use orb::{Feature, Keypoint, OrbConfig, OrbParams, orb_detect, orb_detect_into};
pub use sift::{SiftConfig, SiftFeature, SiftKeypoint, SiftParams, sift_detect};

/// Keeps the `heap.len()`-bounded best items of a stream in a min-heap on `key` (the root is
/// the worst kept item): `O(log n)` per offered item.
///
/// `len` is the number of items in use (`<= heap.len()`). A new item replaces the root when
/// the heap is full and its key is larger.
pub(crate) fn offer_best<T: Copy>(
    heap: &mut [T],
    len: &mut usize,
    item: T,
    key: impl Fn(&T) -> i64,
) {
    let cap = heap.len();
    if cap == 0 {
        return;
    }
    if *len < cap {
        let mut i = *len;
        if let Some(slot) = heap.get_mut(i) {
            *slot = item;
        }
        *len += 1;
        // Sift up.
        while i > 0 {
            let parent = (i - 1) / 2;
            match (heap.get(parent), heap.get(i)) {
                (Some(p), Some(c)) if key(c) < key(p) => {
                    crate::corners::swap_checked(heap, parent, i)
                }
                _ => break,
            }
            i = parent;
        }
        return;
    }
    match heap.first() {
        Some(root) if key(&item) > key(root) => {}
        _ => return,
    }
    if let Some(root) = heap.first_mut() {
        *root = item;
    }
    // Sift down (`min`: `len <= heap.len()`, which the optimiser cannot see).
    let n = (*len).min(heap.len());
    let mut i = 0;
    loop {
        let (l, r) = (2 * i + 1, 2 * i + 2);
        let mut smallest = i;
        let k = |j: usize| heap.get(j).map(&key);
        if l < n && k(l) < k(smallest) {
            smallest = l;
        }
        if r < n && k(r) < k(smallest) {
            smallest = r;
        }
        if smallest == i {
            break;
        }
        crate::corners::swap_checked(heap, i, smallest);
        i = smallest;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offer_best_keeps_the_largest() {
        let mut heap = [0i64; 5];
        let mut len = 0;
        let mut seed = 7u32;
        let mut all = std::vec::Vec::new();
        for _ in 0..200 {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let v = i64::from(seed >> 8);
            all.push(v);
            offer_best(&mut heap, &mut len, v, |v| *v);
        }
        all.sort_unstable();
        let mut kept = heap.to_vec();
        kept.sort_unstable();
        assert_eq!(kept, all[195..]);
        let mut none: [i64; 0] = [];
        let mut l0 = 0;
        offer_best(&mut none, &mut l0, 3, |v| *v);
        assert_eq!(l0, 0);
    }
}
