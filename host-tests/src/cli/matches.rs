//! Point correspondences of two images: read from a CSV file of rows `x1,y1,x2,y2`, or found
//! by matching the ORB features of both images ([`camgeom::features::orb::orb_detect`],
//! default settings) with cross-check, as OpenCV's `BFMatcher(NORM_HAMMING, crossCheck=True)`
//! ([`match_images`]). Structure from motion takes its features from [`orb_features`]
//! (thousands a view, spread by a grid, sub-pixel) and matches them with [`match_features`],
//! or from [`sift_features`] (SIFT, [`camgeom::features::sift`]); [`SfmFeature`] is what it
//! needs of either.

use std::path::{Path, PathBuf};

use camgeom::features::matching::{
    FloatDescriptor, FloatMatch, float_scratch_len, match_float_descriptors_guided,
};
use camgeom::features::orb::{self, Feature, OrbConfig};
use camgeom::features::sift::{self, SiftConfig, SiftFeature};
use camgeom::features::{
    Descriptor, Match, MatchConfig, hamming, l2_squared, match_descriptors,
    match_descriptors_guided,
};
use camgeom::nalgebra::Point2;

use crate::cli::args::MatchesArg;
use crate::error::{Error, ErrorKind, Result};
use crate::images::{GrayImage, load_gray};
use crate::points::read_csv;

/// The columns of a correspondence row.
pub const COLUMNS: [&str; 4] = ["x1", "y1", "x2", "y2"];

/// Point correspondences `(x1, y1) -> (x2, y2)`.
pub type Correspondences = Vec<(Point2<f64>, Point2<f64>)>;

/// Most ORB features per image (`OrbConfig::default().max_features`).
pub const MAX_FEATURES: usize = 500;

/// Cross-check only, as OpenCV's `BFMatcher(NORM_HAMMING, crossCheck=True)` (the settings of
/// the graf1 -> graf3 feature tests).
const CROSS_CHECK: MatchConfig = MatchConfig {
    ratio: 1.0,
    cross_check: true,
    max_distance: 256,
};

/// ORB features of an image file for structure from motion: [`sfm_orb_config`] for its size,
/// keypoints in full-resolution pixels, buffers sized at run time.
pub fn orb_features(path: &Path) -> Result<Vec<Feature>> {
    let img = load_gray(path)?;
    features_with(path, &img, &sfm_orb_config(img.width, img.height))
}

/// ORB features of an image file with OpenCV's settings, [`MAX_FEATURES`] of them (what
/// [`match_images`] matches).
pub fn orb_features_default(path: &Path) -> Result<Vec<Feature>> {
    let img = load_gray(path)?;
    features_with(path, &img, &OrbConfig::default())
}

/// Pixels of the image per ORB feature of [`sfm_orb_config`]: 10 485 at 1536x1024 (FAST
/// finds fewer on some views: 8 480 on herz-jesus-p8). Measured by `examples/pair_accuracy.rs`
/// (median rotation error of the pairs of herz-jesus-p8 and entry-p10): 1 000 px a feature
/// 0.17 and 0.34 deg, 300 px 0.11 and 0.15 deg, 150 px 0.07 and 0.14 deg; 100 px no better.
pub const PIXELS_PER_FEATURE: usize = 150;

/// Grid cells along the longer side of the image in [`sfm_orb_config`].
pub const GRID_CELLS_ALONG: usize = 64;

/// Corners a grid cell keeps in [`sfm_orb_config`].
pub const CELL_KEEP: u8 = 4;

/// ORB settings for structure from motion on a `width x height` image: one feature per
/// [`PIXELS_PER_FEATURE`] pixels (at most `u16::MAX`), sub-pixel positions, and a grid of
/// cells of `1 / GRID_CELLS_ALONG` of the image's longer side (24 px at 1536x1024; in every
/// level's own pixels) keeping [`CELL_KEEP`] corners each, so that the features cover the
/// image instead of crowding on its strongest texture. The rest is OpenCV's (8 levels of
/// scale 1.2, FAST threshold 20).
pub fn sfm_orb_config(width: usize, height: usize) -> OrbConfig {
    let cell = (width.max(height) / GRID_CELLS_ALONG).max(usize::from(orb::MIN_GRID_CELL));
    OrbConfig {
        max_features: (width * height / PIXELS_PER_FEATURE).clamp(1, usize::from(u16::MAX)) as u16,
        grid_cell: u16::try_from(cell).unwrap_or(u16::MAX),
        cell_keep: CELL_KEEP,
        subpixel: true,
        ..OrbConfig::default()
    }
}

fn features_with(path: &Path, img: &GrayImage, config: &OrbConfig) -> Result<Vec<Feature>> {
    let view = img.view().ok_or_else(|| {
        Error::new(
            path,
            ErrorKind::Unsupported(format!("image size {}x{}", img.width, img.height)),
        )
    })?;
    let params = config
        .check()
        .map_err(|e| Error::camgeom(format!("{}: ORB configuration", path.display()), e))?;
    let mut scratch = vec![0u8; orb::scratch_len(img.width, img.height, config.scale_q8)];
    let mut out = vec![Feature::default(); orb::grid_capacity(img.width, img.height, config)];
    let n = orb::orb_detect_into(&view, &params, &mut scratch, &mut out)
        .map_err(|e| Error::camgeom(format!("{}: orb_detect failed", path.display()), e))?;
    out.truncate(n);
    Ok(out)
}

/// The cross-checked matches of two feature sets, `(index in a, index in b)`; `what` names
/// the pair in an error message.
pub fn cross_check(a: &[Feature], b: &[Feature], what: &str) -> Result<Vec<(usize, usize)>> {
    matches_with(a, b, &CROSS_CHECK, what)
}

fn matches_with(
    a: &[Feature],
    b: &[Feature],
    config: &MatchConfig,
    what: &str,
) -> Result<Vec<(usize, usize)>> {
    let da: Vec<Descriptor> = a.iter().map(|f| f.descriptor).collect();
    let db: Vec<Descriptor> = b.iter().map(|f| f.descriptor).collect();
    let mut ms = vec![Match::default(); da.len()];
    let mut scratch = vec![0u32; camgeom::features::matching::scratch_len(db.len())];
    let params = config
        .check()
        .map_err(|e| Error::camgeom(format!("{what}: match configuration"), e))?;
    let n = match_descriptors(&da, &db, &params, &mut scratch, &mut ms)
        .map_err(|e| Error::camgeom(format!("{what}: match_descriptors failed"), e))?;
    Ok(ms[..n]
        .iter()
        .map(|m| (usize::from(m.query), usize::from(m.train)))
        .collect())
}

/// Lowe's ratio test and the mutual check together: what structure from motion matches with
/// (a cross-check alone keeps many wrong matches on repeated building texture).
pub const RATIO_MUTUAL: MatchConfig = MatchConfig {
    ratio: 0.8,
    cross_check: true,
    max_distance: 256,
};

/// The matches of two feature sets that pass the ratio test and the mutual check,
/// `(index in a, index in b)`; `what` names the pair in an error message.
pub fn match_features(a: &[Feature], b: &[Feature], what: &str) -> Result<Vec<(usize, usize)>> {
    matches_with(a, b, &RATIO_MUTUAL, what)
}

/// Correspondences of two images: their ORB keypoints matched with cross-check.
pub fn match_images(a: &Path, b: &Path) -> Result<Correspondences> {
    let (fa, fb) = (orb_features_default(a)?, orb_features_default(b)?);
    let pairs = cross_check(&fa, &fb, &format!("{} -> {}", a.display(), b.display()))?;
    let point = |f: &Feature| Point2::new(f64::from(f.keypoint.x), f64::from(f.keypoint.y));
    Ok(pairs
        .iter()
        .map(|&(i, j)| (point(&fa[i]), point(&fb[j])))
        .collect())
}

/// Reads the correspondences `(x1, y1) -> (x2, y2)` of a CSV file (`-`: stdin).
pub fn read_matches(path: &PathBuf) -> Result<Correspondences> {
    Ok(read_csv(path, &COLUMNS)?
        .rows
        .iter()
        .map(|r| (Point2::new(r[0], r[1]), Point2::new(r[2], r[3])))
        .collect())
}

/// The correspondences of a subcommand's input, `--images A B` (matched with [`match_images`])
/// or else `--matches FILE.csv` ([`read_matches`]): `(source, matches, from_images)`, `source`
/// naming the input in error messages and `from_images` telling feature matches from rows.
pub fn read_input(input: &MatchesArg) -> Result<(String, Correspondences, bool)> {
    match (input.images.as_deref(), input.matches.as_ref()) {
        (Some(images), _) => {
            let [ia, ib] = images else {
                return Err(Error::usage("--images takes two files"));
            };
            let source = format!("{} -> {}", ia.display(), ib.display());
            Ok((source, match_images(ia, ib)?, true))
        }
        (None, Some(path)) => Ok((path.display().to_string(), read_matches(path)?, false)),
        (None, None) => Err(Error::usage("one of --matches and --images is required")),
    }
}

/// Pixels of the image per SIFT feature kept by [`sift_features`] at most (the strongest
/// `|D|`): 10 485 at 1536x1024, as ORB's [`PIXELS_PER_FEATURE`].
pub const SIFT_PIXELS_PER_FEATURE: usize = 150;

/// Contrast threshold of [`sfm_sift_config`]: half OpenCV's 0.04, for about 1.6 times the
/// features (3,700 a view on entry-P10 instead of 2,350). Measured with `camgeom sfm` on all
/// views of entry-P10 and Herz-Jesus-P8 (rotation error median / max): 0.04 gives 0.102 /
/// 0.189° and 0.044 / 0.104°; 0.02 gives 0.050 / 0.118° and 0.041 / 0.081°.
pub const SFM_SIFT_CONTRAST: f32 = 0.02;

/// SIFT settings for structure from motion: OpenCV's (`σ` 1.6, 3 intervals, edge 10) with the
/// contrast threshold [`SFM_SIFT_CONTRAST`], without doubling the image, RootSIFT descriptors
/// (plain SIFT: entry-P10 0.110 / 0.243° against RootSIFT's 0.102 / 0.189° at contrast 0.04).
pub fn sfm_sift_config() -> SiftConfig {
    SiftConfig {
        root: true,
        contrast_threshold: SFM_SIFT_CONTRAST,
        ..SiftConfig::default()
    }
}

/// SIFT features of an image file for structure from motion ([`sfm_sift_config`], the image
/// doubled first when `upsample`), at most one per [`SIFT_PIXELS_PER_FEATURE`] pixels, buffers
/// sized at run time.
pub fn sift_features(path: &Path, upsample: bool) -> Result<Vec<SiftFeature>> {
    let img = load_gray(path)?;
    let config = SiftConfig {
        upsample,
        ..sfm_sift_config()
    };
    sift_features_with(path, &img, &config)
}

/// SIFT features of a decoded image with `config`, at most one per
/// [`SIFT_PIXELS_PER_FEATURE`] pixels.
pub fn sift_features_with(
    path: &Path,
    img: &GrayImage,
    config: &SiftConfig,
) -> Result<Vec<SiftFeature>> {
    let view = img.view().ok_or_else(|| {
        Error::new(
            path,
            ErrorKind::Unsupported(format!("image size {}x{}", img.width, img.height)),
        )
    })?;
    let params = config
        .check()
        .map_err(|e| Error::camgeom(format!("{}: SIFT configuration", path.display()), e))?;
    let mut scratch =
        vec![0.0f32; sift::scratch_len(img.width, img.height, config.intervals, config.upsample)];
    let cap = (img.width * img.height / SIFT_PIXELS_PER_FEATURE).clamp(1, usize::from(u16::MAX));
    let mut out = vec![SiftFeature::default(); cap];
    let n = sift::sift_detect(&view, &params, &mut scratch, &mut out)
        .map_err(|e| Error::camgeom(format!("{}: sift_detect failed", path.display()), e))?;
    out.truncate(n);
    Ok(out)
}

/// What structure from motion needs of a feature: where, at which scale, how far its
/// descriptor is from another's, and matching (ratio test and mutual check, optionally among
/// the pairs a geometry admits).
pub trait SfmFeature: Copy {
    /// The keypoint, pixels.
    fn pixel(&self) -> Point2<f64>;
    /// Input pixels per pixel of the level it was found on (ORB's pyramid scale, SIFT's
    /// `2^octave`): how far a KLT alignment may move it.
    fn level_scale(&self) -> f64;
    /// The size that orders keypoints from finest to coarsest.
    fn fineness(&self) -> f32;
    /// Descriptor distance (Hamming count, or Euclidean).
    fn distance(&self, other: &Self) -> f32;
    /// The matches of `a` and `b` among the pairs `admit` admits, ratio test and mutual check
    /// ([`RATIO_MUTUAL`]), `(index in a, index in b)`.
    fn match_guided(
        a: &[Self],
        b: &[Self],
        admit: impl FnMut(usize, usize) -> bool,
        what: &str,
    ) -> Result<Vec<(usize, usize)>>;
}

fn checked(what: &str) -> Result<camgeom::features::MatchParams> {
    RATIO_MUTUAL
        .check()
        .map_err(|e| Error::camgeom(format!("{what}: match configuration"), e))
}

impl SfmFeature for Feature {
    fn pixel(&self) -> Point2<f64> {
        Point2::new(f64::from(self.keypoint.x), f64::from(self.keypoint.y))
    }
    fn level_scale(&self) -> f64 {
        f64::from(self.keypoint.scale)
    }
    fn fineness(&self) -> f32 {
        self.keypoint.scale
    }
    fn distance(&self, other: &Self) -> f32 {
        hamming(&self.descriptor, &other.descriptor) as f32
    }
    fn match_guided(
        a: &[Self],
        b: &[Self],
        admit: impl FnMut(usize, usize) -> bool,
        what: &str,
    ) -> Result<Vec<(usize, usize)>> {
        let da: Vec<Descriptor> = a.iter().map(|f| f.descriptor).collect();
        let db: Vec<Descriptor> = b.iter().map(|f| f.descriptor).collect();
        let mut out = vec![Match::default(); da.len()];
        let mut scratch = vec![0u32; camgeom::features::matching::scratch_len(db.len())];
        let n = match_descriptors_guided(&da, &db, &checked(what)?, admit, &mut scratch, &mut out)
            .map_err(|e| Error::camgeom(format!("{what}: matching failed"), e))?;
        Ok(out[..n]
            .iter()
            .map(|m| (usize::from(m.query), usize::from(m.train)))
            .collect())
    }
}

impl SfmFeature for SiftFeature {
    fn pixel(&self) -> Point2<f64> {
        Point2::new(f64::from(self.keypoint.x), f64::from(self.keypoint.y))
    }
    fn level_scale(&self) -> f64 {
        f64::from(self.keypoint.octave_scale())
    }
    fn fineness(&self) -> f32 {
        self.keypoint.sigma
    }
    fn distance(&self, other: &Self) -> f32 {
        l2_squared(&self.descriptor, &other.descriptor).sqrt()
    }
    fn match_guided(
        a: &[Self],
        b: &[Self],
        admit: impl FnMut(usize, usize) -> bool,
        what: &str,
    ) -> Result<Vec<(usize, usize)>> {
        let da: Vec<FloatDescriptor> = a.iter().map(|f| f.descriptor).collect();
        let db: Vec<FloatDescriptor> = b.iter().map(|f| f.descriptor).collect();
        let mut out = vec![FloatMatch::default(); da.len()];
        let mut scratch = vec![0u32; float_scratch_len(db.len())];
        let n = match_float_descriptors_guided(
            &da,
            &db,
            &checked(what)?,
            admit,
            &mut scratch,
            &mut out,
        )
        .map_err(|e| Error::camgeom(format!("{what}: matching failed"), e))?;
        Ok(out[..n]
            .iter()
            .map(|m| (usize::from(m.query), usize::from(m.train)))
            .collect())
    }
}
