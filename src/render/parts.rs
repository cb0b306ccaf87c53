//! Splitting a render into parts — pixel tiles and ranges of passes — and
//! merging the parts back into one film.
//!
//! A part renders the passes `passes` of the pixels in `tile` into a film
//! of the whole image and keeps, per pixel, the film's raw state: the
//! weighted sums of the camera samples (XYZ, exact as the film holds them),
//! their total weight (exact), and the sums of the splats (f32). The merge adds those up
//! and reads the image from the sum as the film itself does, so:
//!
//! - **Tiles** of one pass range give the single render's pixels bit for
//!   bit where the plan of samples does not read the whole image (adaptive
//!   sampling off): each pixel's samples, random numbers and sums are the
//!   same, only rendered elsewhere. A tile part of a scene that splats
//!   (`super::circles`) runs all the pass's splat paths, as the single
//!   render does, and keeps the splats that land in its tile: exact, but
//!   every tile pays for the whole image's splats. With adaptive sampling
//!   each part plans its pixels from its own image: unbiased, statistically
//!   equivalent.
//! - **Pass ranges** take the random numbers of their passes (a pass's
//!   numbers depend on its index alone; with adaptive sampling a later
//!   part numbers its samples apart, see `Renderer::render_pass`). The
//!   camera samples' sums and weights are exact ([`super::exact`]: integer
//!   fixed point, so their grouping does not matter), so without adaptive
//!   sampling and without splats the merged image is the single render's
//!   bit for bit. A part's splat density is learned from its own passes
//!   only and its plan from its own image, so with those it is
//!   statistically equivalent.

use super::exact::ExactSum;

/// A rectangle of pixels: columns `x..x + width`, rows `y..y + height`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Tile {
    /// First column.
    pub x: u32,
    /// First row.
    pub y: u32,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
}

impl Tile {
    /// The whole `width`×`height` image.
    pub fn whole(width: u32, height: u32) -> Self {
        Self {
            x: 0,
            y: 0,
            width,
            height,
        }
    }

    /// Parses `X,Y,W,H`, checked against a `width`×`height` image.
    pub fn parse(text: &str, width: u32, height: u32) -> Result<Self, String> {
        let numbers: Vec<u32> = text
            .split(',')
            .map(|p| p.trim().parse::<u32>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("'{text}' is not X,Y,W,H in pixels"))?;
        let [x, y, w, h] = numbers[..] else {
            return Err(format!("'{text}' is not X,Y,W,H in pixels"));
        };
        let tile = Self {
            x,
            y,
            width: w,
            height: h,
        };
        tile.check(width, height)?;
        Ok(tile)
    }

    /// Band `index` of `count` bands of whole rows, as even as rows allow.
    pub fn band(count: u32, index: u32, width: u32, height: u32) -> Result<Self, String> {
        if count == 0 || count > height {
            return Err(format!(
                "{count} tiles: between 1 and the image's {height} rows"
            ));
        }
        if index >= count {
            return Err(format!(
                "tile index {index} is outside the valid range 0 to {}",
                count - 1
            ));
        }
        let edge = |i: u32| (u64::from(height) * u64::from(i) / u64::from(count)) as u32;
        Ok(Self {
            x: 0,
            y: edge(index),
            width,
            height: edge(index + 1) - edge(index),
        })
    }

    /// An error unless the tile is non-empty and inside the image.
    pub fn check(&self, width: u32, height: u32) -> Result<(), String> {
        let inside = u64::from(self.x) + u64::from(self.width) <= u64::from(width)
            && u64::from(self.y) + u64::from(self.height) <= u64::from(height);
        if self.width == 0 || self.height == 0 || !inside {
            return Err(format!(
                "tile {} is empty or not inside the {width}×{height} image",
                self.describe()
            ));
        }
        Ok(())
    }

    /// `X,Y,W,H`.
    pub fn describe(&self) -> String {
        format!("{},{},{},{}", self.x, self.y, self.width, self.height)
    }

    /// Whether row `y` crosses the tile.
    pub fn contains_row(&self, y: u32) -> bool {
        (self.y..self.y + self.height).contains(&y)
    }

    /// Whether pixel (`x`, `y`) is in the tile.
    pub fn contains(&self, x: u32, y: u32) -> bool {
        self.contains_row(y) && (self.x..self.x + self.width).contains(&x)
    }

    /// Pixels in the tile.
    pub fn pixels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// Whether the two tiles share a pixel.
    pub fn overlaps(&self, other: &Self) -> bool {
        self.x < other.x + other.width
            && other.x < self.x + self.width
            && self.y < other.y + other.height
            && other.y < self.y + self.height
    }
}

/// Passes `start..end` (0-based, end excluded, as a Rust range).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PassRange {
    /// First pass.
    pub start: u32,
    /// One past the last pass.
    pub end: u32,
}

impl PassRange {
    /// Parses `A..B` within a render of `spp` passes.
    pub fn parse(text: &str, spp: u32) -> Result<Self, String> {
        let fail = || format!("'{text}' is not START..END (passes from 0, END excluded)");
        let (a, b) = text.split_once("..").ok_or_else(fail)?;
        let start: u32 = a.trim().parse().map_err(|_| fail())?;
        let end: u32 = b.trim().parse().map_err(|_| fail())?;
        if start >= end {
            return Err(format!("passes '{text}' are empty or reversed"));
        }
        if end > spp {
            return Err(format!(
                "passes '{text}' go past the render's {spp} passes (spp)"
            ));
        }
        Ok(Self { start, end })
    }

    /// `A..B`.
    pub fn describe(&self) -> String {
        format!("{}..{}", self.start, self.end)
    }

    /// Passes in the range.
    pub fn len(&self) -> u32 {
        self.end - self.start
    }

    /// Whether the range holds no pass.
    pub fn is_empty(&self) -> bool {
        self.end <= self.start
    }
}

/// What one part of a render holds, per pixel of the whole image (zero
/// outside its tile).
#[derive(Clone, Debug, PartialEq)]
pub struct PartData {
    /// Its passes.
    pub passes: PassRange,
    /// Its pixels.
    pub tile: Tile,
    /// Weighted sums of the camera samples' XYZ (Y in cd m⁻²), exact.
    pub sums: Vec<[ExactSum; 3]>,
    /// Total weight of each pixel's camera samples, exact.
    pub weights: Vec<ExactSum>,
    /// The part of `sums` and `weights` from the samples drawn in the
    /// pixels' left parts under a [`super::HalfMirror`] (empty where the
    /// render has none).
    pub left_sums: Vec<[ExactSum; 3]>,
    /// See `left_sums`.
    pub left_weights: Vec<ExactSum>,
    /// Sums of the splats (empty where the render does not splat).
    pub splat_sums: Vec<[f32; 3]>,
    /// The part of `splat_sums` that landed in the pixels' left parts under
    /// a [`super::HalfMirror`] (empty without one or without splats).
    pub splat_left: Vec<[f32; 3]>,
    /// Paths splatted (over the whole image).
    pub splat_paths: u64,
    /// Camera samples discarded (in the tile).
    pub camera_discarded: u64,
    /// Splats discarded (over the whole image).
    pub splat_discarded: u64,
}

/// `v` where `inside` holds, zero elsewhere.
pub(super) fn pick<T: Copy + Default>(v: &[[T; 3]], inside: impl Fn(usize) -> bool) -> Vec<[T; 3]> {
    (0..v.len())
        .map(|i| if inside(i) { v[i] } else { [T::default(); 3] })
        .collect()
}

/// Checks that `parts` (pass range, tile) cover passes `0..spp` of a
/// `width`×`height` image once each: the pass ranges do not overlap and
/// leave no pass out, and each range's tiles neither overlap nor leave a
/// pixel out. The error says what is wrong.
pub fn check_cover(
    parts: &[(PassRange, Tile)],
    spp: u32,
    width: u32,
    height: u32,
) -> Result<(), String> {
    let mut ranges: Vec<PassRange> = parts.iter().map(|p| p.0).collect();
    ranges.sort();
    ranges.dedup();
    let mut next = 0;
    for r in &ranges {
        if r.start < next {
            return Err(format!(
                "pass ranges {} and an earlier one overlap",
                r.describe()
            ));
        }
        if r.start > next {
            return Err(format!("passes {next}..{} are missing", r.start));
        }
        next = r.end;
    }
    if next != spp {
        return Err(format!("passes {next}..{spp} are missing"));
    }
    let image = u64::from(width) * u64::from(height);
    for r in &ranges {
        let tiles: Vec<&Tile> = parts.iter().filter(|p| p.0 == *r).map(|p| &p.1).collect();
        for (i, a) in tiles.iter().enumerate() {
            if let Some(b) = tiles[i + 1..].iter().find(|b| a.overlaps(b)) {
                return Err(format!(
                    "tiles {} and {} of passes {} overlap",
                    a.describe(),
                    b.describe(),
                    r.describe()
                ));
            }
        }
        let covered: u64 = tiles.iter().map(|t| t.pixels()).sum();
        if covered != image {
            return Err(format!(
                "tiles of passes {} cover {covered} of the image's {image} pixels: a tile is missing",
                r.describe()
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_parse_and_bands_cover_the_image() {
        assert_eq!(
            Tile::parse("0, 8,16,8", 16, 16).unwrap(),
            Tile {
                x: 0,
                y: 8,
                width: 16,
                height: 8
            }
        );
        for bad in ["0,0,17,1", "0,0,0,1", "1,2,3", "a,b,c,d", "0,15,1,2"] {
            assert!(Tile::parse(bad, 16, 16).is_err(), "{bad}");
        }
        let bands: Vec<Tile> = (0..3).map(|i| Tile::band(3, i, 10, 7).unwrap()).collect();
        assert_eq!(bands.iter().map(|t| t.height).sum::<u32>(), 7);
        assert!(Tile::band(3, 3, 10, 7).is_err() && Tile::band(8, 0, 10, 7).is_err());
        let parts: Vec<(PassRange, Tile)> = bands
            .iter()
            .map(|&t| (PassRange { start: 0, end: 4 }, t))
            .collect();
        check_cover(&parts, 4, 10, 7).unwrap();
    }

    #[test]
    fn covers_that_miss_or_overlap_are_refused() {
        let whole = Tile::whole(4, 4);
        let top = Tile::band(2, 0, 4, 4).unwrap();
        let r = |start, end| PassRange { start, end };
        let says = |parts: &[(PassRange, Tile)], needle: &str| {
            let e = check_cover(parts, 8, 4, 4).unwrap_err();
            assert!(e.contains(needle), "{e}");
        };
        says(&[(r(0, 4), whole), (r(3, 8), whole)], "overlap");
        says(&[(r(0, 4), whole), (r(5, 8), whole)], "4..5 are missing");
        says(&[(r(0, 4), whole)], "4..8 are missing");
        says(&[(r(0, 8), top)], "a tile is missing");
        says(&[(r(0, 8), whole), (r(0, 8), top)], "overlap");
        check_cover(
            &[
                (r(0, 3), whole),
                (r(3, 8), top),
                (r(3, 8), Tile::band(2, 1, 4, 4).unwrap()),
            ],
            8,
            4,
            4,
        )
        .unwrap();
        assert!(PassRange::parse("4..4", 8).is_err() && PassRange::parse("2..9", 8).is_err());
        assert_eq!(PassRange::parse("2..8", 8).unwrap(), r(2, 8));
    }
}
