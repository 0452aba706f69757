//! Image features: FAST corners, ORB descriptors and brute-force Hamming matching.
//!
//! Everything here is allocation-free: detectors write into fixed-capacity
//! [`heapless::Vec`]s or caller slices and take their working memory as one caller-provided
//! byte slice whose length a `const fn` gives ([`fast::scratch_len`], [`orb::scratch_len`],
//! [`matching::scratch_len`]). The work of every function is bounded by the image size and
//! the capacities (stated per function).
//!
//! | module | what |
//! |---|---|
//! | [`fast`] | FAST-9 corners on the 16-pixel Bresenham circle with 3x3 non-maximum suppression, integer Harris response |
//! | [`orb`] | ORB: multi-scale FAST + Harris selection, intensity-centroid orientation, steered 256-bit BRIEF |
//! | [`matching`] | Hamming distance, brute-force matching with Lowe's ratio test and cross-check |

pub mod fast;
pub mod matching;
pub mod orb;

pub use fast::{Corner, FastConfig, fast_detect, harris_response};
pub use matching::{Descriptor, Match, MatchConfig, hamming, match_descriptors};
pub use orb::{Feature, Keypoint, OrbConfig, orb_detect};

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
