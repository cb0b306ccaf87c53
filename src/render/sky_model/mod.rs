//! An approximate sky, computed from the same atmosphere the path tracer
//! renders (its tables in about a second, a view of them in
//! tens of milliseconds): the preview's first frame, shown before the
//! first Monte Carlo pass is in.
//!
//! **Method** (Hillaire 2020, "A Scalable and Production Ready Sky and
//! Atmosphere Rendering Technique", *Computer Graphics Forum* 39(4)): the
//! same coefficients, phase functions and sun ([`Medium`], [`SpectralLanes`](super::medium::SpectralLanes))
//! at 16 wavelengths, with three approximations, each a table (the second
//! computed as Bruneton & Neyret do):
//!
//! 1. *Sunlight* reaching a point is the straight-line transmittance from
//!    its column amounts toward the sun ([`Medium::sun_columns`]); zero in
//!    the planet's shadow.
//! 2. *Light scattered twice or more* at a point depends on its altitude,
//!    the solar zenith and the view's direction, order by order (Bruneton
//!    & Neyret 2008, "Precomputed Atmospheric Scattering", *Computer
//!    Graphics Forum* 27(4)): the table of order n + 1 holds
//!    J_X(v) = Σ_ω L_n(ω) P_X(ω·v) Δω for the Rayleigh and aerosol phase
//!    functions P_X, L_n the light of order n arriving from ω (the air's,
//!    marched through the table of order n, and the ground's, lit by the
//!    sky of order n − 1). J is kept as a table over ν, the view's cosine
//!    to the sun (dense about the sun, where haze's forward peak makes
//!    the aureole), times a smooth factor over the view's zenith and
//!    azimuth (the low sky's long paths, the ground's light seen from
//!    above), each entry the ratio of J at that view to the ν table's.
//!    Orders 2–5 are computed; the rest are each entry's tail, its ratio
//!    of orders falling toward the whole field's.
//!    The sums over directions weight each by the phase function
//!    averaged over its cell (a haze's or dust's forward peak is narrower
//!    than their spacing), scaled per view so that they sum the phase
//!    function to one, as its integral is.
//!    Hillaire's isotropic factor for the orders past the second takes
//!    their light as made at the point itself and isotropic; at the
//!    horizon and at twilight it arrives from far away, and that factor
//!    left out a fifth of it. The tables hold every solar zenith and do
//!    not depend on the sun's or the observer's place: they are kept
//!    while only those change ([`ModelTables::shared`]).
//! 3. *The sky seen from the observer* is smooth in direction once the
//!    phase functions are taken out: along a view ray the angle to the sun
//!    is fixed, so the single scattering is P_R(θ) A_R + P_A(θ) A_A with
//!    A = ∫ T σ T_sun dt, and the rest (Ψ, the ground) is a third term B.
//!    A, B are tabulated over elevation (dense at the horizon) and azimuth
//!    from the sun; each pixel then evaluates the phase functions at its
//!    own angle, so the aureole is as sharp as the phase function. B is
//!    tabulated over the shape of the multiple scattering's source about
//!    the sun at the observer, and multiplied by it at each pixel's own
//!    angle likewise.
//!
//! The ground is Lambertian, lit by the sun and by the model's own sky
//! (its irradiance tabulated over the solar zenith). The spectrum is the
//! atmosphere's response at 16 wavelengths (360–830 nm), linear between
//! them, times the sun's spectrum at the colour-matching functions' 1 nm
//! grid. The sun's disc is left out.
//!
//! It is an approximation, never a reference: its error against the
//! converged path tracer is measured per preset (`skyrender bench`,
//! `first_frame_error`; `BENCHMARKS.md`).

use std::f64::consts::PI;
use std::sync::Arc;

use glam::DVec3;
use rayon::prelude::*;

use super::camera::Camera;
use super::directions::horizon_cosine;
use super::lanes::LaneTable;
use super::medium::{Lanes, Medium, LANES};
use crate::output::RgbImage;
use crate::spectrum::{xyz_to_rec709, ColourMatching, K_M};

mod geometric;
mod optics;
mod orders;
mod stored;
mod sun;

use optics::{node_wavelength, Gathered, Optics, Sources, Spectrum, MS_VIEW_ANGLES, NODES};
pub use orders::{forget_shared_tables, keep_shared_tables_on_disk, ModelTables};

/// Steps of a view ray's march (at 32, the midday sky read 1.3 % off the
/// path tracer's, 1.0 % at 48 and at 64).
const VIEW_STEPS: usize = 48;
/// The longest a step of a short view ray may be, m: a ray shorter than
/// [`VIEW_STEPS`] of these takes proportionally fewer steps (at least
/// [`MIN_VIEW_STEPS`]). From the ground most of the rows below the
/// horizon end on it within a few hundred metres, where the air, its
/// sunlight and its multiply scattered light hardly change; a full march
/// there spends half the observer's table on rays that hold a few per
/// cent of the light they show. A full-length ray's first steps from the
/// ground are as short (the steps grow as the square from its lowest
/// point, [`optics`]).
const SHORT_STEP_M: f64 = 40.0;
/// See [`SHORT_STEP_M`].
const MIN_VIEW_STEPS: usize = 4;

/// Steps of the view march of a ray `length_m` long.
fn view_steps(length_m: f64) -> usize {
    ((length_m / SHORT_STEP_M).ceil() as usize).clamp(MIN_VIEW_STEPS, VIEW_STEPS)
}

/// Rows (elevation) and columns (azimuth from the sun, 0–180°) of the
/// observer's sky table.
const VIEW_ROWS: usize = 64;
/// See [`VIEW_ROWS`]; spaced as [`column_azimuth`].
const VIEW_COLUMNS: usize = 48;

/// The azimuth from the sun's (radians) of fractional `column` of the
/// observer's table: φ = π (c/(n − 1))², 0.08° beside the sun, 7.6° at
/// its back. A column holds B over the aureole's shape at the observer,
/// and along a view beside a low sun the air's own aureole widens and
/// narrows with altitude: B over the shape changes within degrees of the
/// sun's azimuth. With 32 even columns (5.8° apart) the first frame at
/// Mars sunset read 1.04–1.10× the path tracer's 6–15° beside the sun
/// at the horizon and 0.96× just above it, 7.4 % off over the image;
/// with 128 even columns or these 48, 5.8 % (256×128, the other tables
/// as they were then).
fn column_azimuth(column: f64) -> f64 {
    let u = column / (VIEW_COLUMNS - 1) as f64;
    PI * u * u
}

/// The first row above the horizon ([`Rows`]: the horizon lies half-way
/// between the two middle rows).
const HORIZON_ROW: usize = VIEW_ROWS / 2;
const _: () = assert!(
    VIEW_ROWS.is_multiple_of(2),
    "the horizon must fall between two rows"
);

/// The approximate sky of one scene.
pub struct SkyModel {
    /// The observer's sky: per texel, A_R, A_A and B at each wavelength.
    view: Vec<[Spectrum; 3]>,
    /// Zenith, the horizontal toward the sun, and across, at the observer.
    frame: [DVec3; 3],
    /// The elevations of the view table's rows.
    rows: Rows,
    sun_direction: DVec3,
    /// The atmosphere's tables (the phase functions at each wavelength).
    tables: Arc<ModelTables>,
    /// The shape of B about the sun: the source of the light scattered
    /// more than once at the observer, at each of the ν table's view–sun
    /// cosines ([`aureole_shape`]).
    aureole: [Spectrum; MS_VIEW_ANGLES],
    /// Per colour (X, Y, Z), its value per unit response at each node:
    /// K_M ∫ E_sun h_k x̄ dλ.
    xyz_weights: [Spectrum; 3],
}

/// The model's light field: the radiance arriving at any point of the
/// atmosphere from any direction, per unit solar irradiance, at the
/// model's wavelengths — the model's tables without the observer's view
/// table. A view ray's march through the tables costs about as much as a
/// few path vertices, so the field serves as a control variate's
/// approximation of the light at a point (`crate::render::tables`).
pub struct ModelField {
    tables: Arc<ModelTables>,
    sun_direction: DVec3,
}

impl ModelField {
    /// The field of `tables`' atmosphere lit along `sun_direction`.
    pub fn from_tables(tables: Arc<ModelTables>, sun_direction: DVec3) -> Self {
        Self {
            tables,
            sun_direction,
        }
    }

    fn optics<'a>(&'a self, medium: &'a Medium) -> Optics<'a> {
        Optics {
            medium,
            groups: &self.tables.groups,
            phases: &self.tables.phases,
            sun_direction: self.sun_direction,
        }
    }

    /// The radiance arriving at `x` looking along unit `dir` in `medium`
    /// (the one the field was built for), per unit solar irradiance, at
    /// each of the model's wavelengths ([`Self::node_nm`]); the sun's disc
    /// left out.
    pub fn radiance(&self, medium: &Medium, x: DVec3, dir: DVec3) -> [f64; NODES] {
        self.radiance_marched(medium, x, dir, VIEW_STEPS)
    }

    /// [`Self::radiance`] by a march of `steps` steps (more steps, less
    /// error, more time; the observer's view takes 48).
    pub fn radiance_marched(
        &self,
        medium: &Medium,
        x: DVec3,
        dir: DVec3,
        steps: usize,
    ) -> [f64; NODES] {
        let optics = self.optics(medium);
        let tables = &self.tables;
        let g = optics.march(x, dir, steps, Sources::all(&tables.ms, &tables.sky));
        let (pr, pa) = tables.phases.at(dir.dot(self.sun_direction));
        std::array::from_fn(|n| pr[n] * g.rayleigh[n] + pa[n] * g.aerosol[n] + g.isotropic[n])
    }

    /// The wavelength of the model's node `k` < [`MODEL_NODES`], nm.
    pub fn node_nm(k: usize) -> f64 {
        node_wavelength(k)
    }

    /// The two model nodes about `wavelength_nm`, as the lower one's index
    /// m and the weight f of node m + 1 (linear interpolation; clamped to
    /// the nodes' range).
    pub fn node_blend(wavelength_nm: f64) -> (usize, f64) {
        let step_nm = node_wavelength(1) - node_wavelength(0);
        optics::split((wavelength_nm - node_wavelength(0)) / step_nm, NODES)
    }

    /// The atmosphere's tables the field reads.
    pub fn tables(&self) -> &Arc<ModelTables> {
        &self.tables
    }
}

/// Wavelengths at which the model is computed ([`ModelField::node_nm`]).
pub const MODEL_NODES: usize = NODES;

impl SkyModel {
    /// The model of `tables`' atmosphere `medium` lit along
    /// `sun_direction`, seen from `observer_m`, in the sun and colours of
    /// `lane_table` and `cmf`.
    pub fn from_tables(
        tables: Arc<ModelTables>,
        medium: &Medium,
        lane_table: &LaneTable,
        cmf: &ColourMatching,
        sun_direction: DVec3,
        observer_m: DVec3,
    ) -> Self {
        let field = ModelField::from_tables(tables, sun_direction);
        let nodes: Vec<f64> = (0..NODES).map(node_wavelength).collect();
        let optics = field.optics(medium);
        let (ms, sky) = (&field.tables.ms, &field.tables.sky);
        let zenith = observer_m.normalize();
        let toward_sun = sun_direction - zenith * sun_direction.dot(zenith);
        let x = if toward_sun.length() > 1e-9 {
            toward_sun.normalize()
        } else {
            zenith.any_orthonormal_vector()
        };
        let frame = [zenith, x, zenith.cross(x)];
        let r = observer_m.length();
        let rows = Rows::new(medium.planet_radius_m, medium.top_radius_m, r);
        let aureole = aureole_shape(&optics, ms, observer_m);
        // A row's directions share their elevation: one fan of marches.
        let view = (0..VIEW_ROWS)
            .into_par_iter()
            .flat_map_iter(|row| {
                let elevation = rows.elevation(row as f64);
                let dirs: [DVec3; VIEW_COLUMNS] = std::array::from_fn(|column| {
                    let azimuth = column_azimuth(column as f64);
                    direction(&frame, elevation, azimuth)
                });
                let mut gathered: [Gathered; VIEW_COLUMNS] =
                    std::array::from_fn(|_| Gathered::default());
                let steps = medium
                    .span(observer_m, dirs[0])
                    .map_or(VIEW_STEPS, |s| view_steps(s.t_exit - s.t_enter));
                optics.march_fan(
                    observer_m,
                    &dirs,
                    steps,
                    Sources::all(ms, sky),
                    &mut gathered,
                );
                gathered.into_iter().zip(dirs).map(|(g, dir)| {
                    let shape = shape_at(&aureole, dir.dot(sun_direction));
                    [
                        g.rayleigh,
                        g.aerosol,
                        std::array::from_fn(|n| g.isotropic[n] / shape[n]),
                    ]
                })
            })
            .collect();
        Self {
            view,
            frame,
            rows,
            sun_direction,
            xyz_weights: xyz_weights(medium, lane_table, cmf, &nodes),
            tables: field.tables,
            aureole,
        }
    }

    /// The model's radiance along `dir` from the observer as CIE XYZ (Y, the
    /// luminance, in cd m⁻²), the sun's disc left out.
    pub fn xyz(&self, dir: DVec3) -> [f64; 3] {
        let [zenith, x, y] = self.frame;
        let elevation = dir.dot(zenith).clamp(-1.0, 1.0).asin();
        let azimuth = dir.dot(y).atan2(dir.dot(x)).abs();
        // The horizon lies between the two middle rows: a direction takes
        // the rows of its own side only, the sky's never mixed with the
        // ground's just below it.
        let row = if elevation >= self.rows.horizon_rad {
            self.rows.row(elevation).max(HORIZON_ROW as f64)
        } else {
            self.rows.row(elevation).min((HORIZON_ROW - 1) as f64)
        };
        let column = (azimuth / PI).sqrt() * (VIEW_COLUMNS - 1) as f64;
        let [ar, aa, b] = bilinear(&self.view, (row, VIEW_ROWS), (column, VIEW_COLUMNS));
        let nu = dir.dot(self.sun_direction);
        let (pr, pa) = self.tables.phases.at(nu);
        let shape = shape_at(&self.aureole, nu);
        let response: Spectrum =
            std::array::from_fn(|n| pr[n] * ar[n] + pa[n] * aa[n] + b[n] * shape[n]);
        self.xyz_weights
            .map(|weights| response.iter().zip(weights).map(|(r, w)| r * w).sum())
    }

    /// The model seen through `camera`: linear Rec.709, Y in cd m⁻²,
    /// each pixel the average over its area (the path tracer's box
    /// filter; a sub-pixel position with no ray counts as black).
    ///
    /// Four stratified positions per pixel; where their luminances differ
    /// by more than a tenth of the largest (the horizon, the limb seen
    /// from orbit, the edge of a fisheye's circle) the pixel is averaged
    /// over an 8 × 8 grid instead: there the light drops by orders of
    /// magnitude within a pixel, and one value at its centre is off by as
    /// much.
    pub fn image(&self, camera: &Camera, width: u32, height: u32) -> RgbImage {
        // Which side of the horizon each pixel corner looks to (`None`:
        // no ray), once per corner: four pixels share it.
        let corners_wide = width as usize + 1;
        let corners: Vec<Option<bool>> = (0..corners_wide * (height as usize + 1))
            .into_par_iter()
            .map(|c| {
                let (x, y) = ((c % corners_wide) as f64, (c / corners_wide) as f64);
                self.above_horizon(camera, x, y)
            })
            .collect();
        let pixels = (0..width as usize * height as usize)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % width as usize, i / width as usize);
                let (px, py) = (x as f64, y as f64);
                let corner = |dx: usize, dy: usize| corners[(y + dy) * corners_wide + x + dx];
                let crossed = [corner(0, 0), corner(1, 0), corner(0, 1), corner(1, 1)];
                let at = |fx: f64, fy: f64| {
                    camera
                        .direction(px + fx, py + fy)
                        .map_or([0.0; 3], |dir| self.xyz(dir))
                };
                let mean = |grid: usize| {
                    let mut sum = [0.0; 3];
                    for k in 0..grid * grid {
                        let step = 1.0 / grid as f64;
                        let xyz = at(
                            ((k % grid) as f64 + 0.5) * step,
                            ((k / grid) as f64 + 0.5) * step,
                        );
                        for (s, v) in sum.iter_mut().zip(xyz) {
                            *s += v;
                        }
                    }
                    sum.map(|s| s / (grid * grid) as f64)
                };
                let crossed =
                    crossed.iter().all(Option::is_some) && crossed.iter().any(|&c| c != crossed[0]);
                if let Some(xyz) = crossed
                    .then(|| self.across_the_horizon(camera, px, py))
                    .flatten()
                {
                    return xyz_to_rec709(xyz).map(|v| v as f32);
                }
                let four = [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)]
                    .map(|(fx, fy)| at(fx, fy));
                let luminance = four.map(|xyz| xyz[1]);
                let (low, high) = luminance
                    .iter()
                    .fold((f64::INFINITY, 0.0_f64), |(l, h), &y| (l.min(y), h.max(y)));
                let xyz = if high - low > EDGE_CONTRAST * high {
                    mean(EDGE_SAMPLES)
                } else {
                    std::array::from_fn(|c| four.iter().map(|v| v[c]).sum::<f64>() / 4.0)
                };
                xyz_to_rec709(xyz).map(|v| v as f32)
            })
            .collect();
        RgbImage {
            width,
            height,
            pixels,
        }
    }

    /// Whether the view through `camera` at pixel position (`x`, `y`)
    /// lies at or above the horizon; `None` where the camera has no ray.
    fn above_horizon(&self, camera: &Camera, x: f64, y: f64) -> Option<bool> {
        let horizon = self.rows.horizon_rad.sin();
        camera
            .direction(x, y)
            .map(|d| d.normalize().dot(self.frame[0]) >= horizon)
    }

    /// The mean of a pixel that the horizon crosses (its corners on both
    /// sides, [`Self::image`] checks), or `None` where a column's end has
    /// no ray: per column of
    /// [`EDGE_SAMPLES`], the point where the horizon crosses it is found
    /// by bisection, and the sky above it and the ground below it are
    /// each averaged over their own length. An observer a few metres up
    /// sees the horizon a few hundredths of a degree below the horizontal:
    /// a pixel just below it holds a sliver of the bright horizon sky,
    /// which no grid of sample points finds.
    fn across_the_horizon(&self, camera: &Camera, px: f64, py: f64) -> Option<[f64; 3]> {
        let above = |fx: f64, fy: f64| self.above_horizon(camera, px + fx, py + fy);
        let mut sum = [0.0; 3];
        // The mean over a part of a column, from its end at the horizon
        // (`edge`) a length `length` away (signed), with points crowding
        // toward the horizon, where the light changes fastest (the ground's
        // haze thickens toward it): y = edge + length u², dy = 2 length u du.
        let mut add = |fx: f64, edge: f64, length: f64| {
            for k in 0..EDGE_SAMPLES {
                let u = (k as f64 + 0.5) / EDGE_SAMPLES as f64;
                if let Some(dir) = camera.direction(px + fx, py + edge + length * u * u) {
                    let xyz = self.xyz(dir);
                    for (s, v) in sum.iter_mut().zip(xyz) {
                        *s += v * 2.0 * length.abs() * u / EDGE_SAMPLES as f64;
                    }
                }
            }
        };
        for c in 0..EDGE_SAMPLES {
            let fx = (c as f64 + 0.5) / EDGE_SAMPLES as f64;
            let (top, bottom) = (above(fx, 0.0)?, above(fx, 1.0)?);
            if top == bottom {
                add(fx, 0.0, 1.0);
                continue;
            }
            let (mut low, mut high) = (0.0, 1.0);
            for _ in 0..30 {
                let mid = 0.5 * (low + high);
                if above(fx, mid)? == top {
                    low = mid;
                } else {
                    high = mid;
                }
            }
            add(fx, low, -low);
            add(fx, high, 1.0 - high);
        }
        Some(sum.map(|s| s / EDGE_SAMPLES as f64))
    }
}

/// The source of the light scattered more than once at `observer_m` (its
/// altitude clamped into the air), σ_R J_R + σ_A J_A from the ν table
/// alone, at each of the table's view–sun cosines, each wavelength's
/// scaled to its largest and kept above a millionth of it.
///
/// Along a view ray the view–sun cosine ν is fixed, so the table's
/// multiply scattered light B is, like that source, piecewise linear in
/// the ν table's index about the sun: an aureole a few degrees wide
/// where the haze's or dust's forward peak scatters twice. The view
/// table's columns (5.8° apart) hold B over this shape, which is smooth
/// in azimuth, and each pixel multiplies it back at its own ν, as the
/// once-scattered light's phase functions are.
fn aureole_shape(
    optics: &Optics<'_>,
    ms: &optics::MsTable,
    observer_m: DVec3,
) -> [Spectrum; MS_VIEW_ANGLES] {
    let medium = optics.medium;
    let r = observer_m
        .length()
        .clamp(medium.planet_radius_m, medium.top_radius_m);
    let x = observer_m.normalize() * r;
    let mu_s = x.normalize().dot(optics.sun_direction);
    let mut sigma = [[0.0; NODES]; 2];
    for (g, lanes) in optics.groups.iter().enumerate() {
        let c = medium.coefficients(r, lanes);
        for j in 0..LANES {
            sigma[0][g * LANES + j] = c.rayleigh[j];
            sigma[1][g * LANES + j] = c.aerosol_scattering[j];
        }
    }
    let mut shape: [Spectrum; MS_VIEW_ANGLES] = std::array::from_fn(|a| {
        let [jr, ja] = ms.about_sun(r, mu_s, a);
        std::array::from_fn(|n| sigma[0][n] * jr[n] + sigma[1][n] * ja[n])
    });
    for n in 0..NODES {
        let peak = shape.iter().map(|s| s[n]).fold(0.0, f64::max);
        for s in &mut shape {
            s[n] = if peak > 0.0 && peak.is_finite() {
                (s[n] / peak).max(1e-6)
            } else {
                1.0
            };
        }
    }
    shape
}

/// [`aureole_shape`] at view–sun cosine `nu`, linear in the ν table's
/// index as the table's own look-ups are.
fn shape_at(shape: &[Spectrum; MS_VIEW_ANGLES], nu: f64) -> Spectrum {
    let (a, f) = optics::split(optics::view_cosine_index(nu), MS_VIEW_ANGLES);
    std::array::from_fn(|n| shape[a][n] + f * (shape[a + 1][n] - shape[a][n]))
}

/// The spread of a pixel's four first luminances, relative to the
/// largest, past which [`SkyModel::image`] averages it over a finer grid.
const EDGE_CONTRAST: f64 = 0.1;
/// Positions per axis of [`SkyModel::image`]'s finer grid.
const EDGE_SAMPLES: usize = 8;

/// K_M ∫ E_sun(λ) h_k(λ) x̄(λ) dλ for the hat function h_k of each node,
/// on the colour-matching table's own grid.
fn xyz_weights(
    medium: &Medium,
    lane_table: &LaneTable,
    cmf: &ColourMatching,
    nodes: &[f64],
) -> [Spectrum; 3] {
    // The sun at the grid's wavelengths, four at a time.
    let grid: Vec<f64> = cmf.grid_nm().collect();
    let sun: Vec<f64> = grid
        .chunks(LANES)
        .flat_map(|w| {
            let lanes = lane_table.lanes(Lanes::from_fn(|j| w[j.min(w.len() - 1)]), LANES, medium);
            (0..w.len()).map(move |j| lanes.sun_irradiance[j])
        })
        .collect();
    let step = nodes[1] - nodes[0];
    let per_node: [[f64; 3]; NODES] = std::array::from_fn(|k| {
        let xyz = cmf.integrate(|w| {
            let i = grid.partition_point(|&g| g < w);
            let hat = (1.0 - (w - nodes[k]).abs() / step).max(0.0);
            // Beyond the end nodes the end node holds the response.
            let hat = if (k == 0 && w < nodes[0]) || (k == NODES - 1 && w > nodes[NODES - 1]) {
                1.0
            } else {
                hat
            };
            sun.get(i).copied().unwrap_or(0.0) * hat
        });
        xyz.map(|v| K_M * v)
    });
    std::array::from_fn(|c| std::array::from_fn(|k| per_node[k][c]))
}

/// The observer's sky table's rows: elevations crowding about the horizon
/// (at `horizon_rad`), where the sky changes fastest (Hillaire's mapping),
/// the upper half ending at `top_rad`, the highest elevation at which a
/// view ray still meets the air (π/2 inside the atmosphere; the grazing
/// ray of its top from outside, where the bright limb is a few tenths of
/// a degree high and would otherwise fall between two rows).
#[derive(Clone, Copy)]
struct Rows {
    horizon_rad: f64,
    top_rad: f64,
}

impl Rows {
    /// The rows of an observer `r_m` from the centre of a planet of
    /// radius `planet_radius_m` with an atmosphere up to `top_radius_m`.
    fn new(planet_radius_m: f64, top_radius_m: f64, r_m: f64) -> Self {
        // The horizon dips by acos(R/r) below the horizontal: its elevation
        // is the arcsine of its zenith cosine, −√(1 − (R/r)²).
        let below = |radius_m: f64| {
            horizon_cosine(radius_m, r_m.max(radius_m))
                .clamp(-1.0, 0.0)
                .asin()
        };
        let horizon_rad = below(planet_radius_m);
        let top_rad = if r_m > top_radius_m {
            below(top_radius_m)
        } else {
            PI / 2.0
        };
        Self {
            horizon_rad,
            top_rad,
        }
    }

    /// Elevation of fractional `row`.
    fn elevation(&self, row: f64) -> f64 {
        let v = row / (VIEW_ROWS - 1) as f64;
        if v >= 0.5 {
            let u = 2.0 * v - 1.0;
            self.horizon_rad + u * u * (self.top_rad - self.horizon_rad)
        } else {
            let u = 1.0 - 2.0 * v;
            self.horizon_rad - u * u * (PI / 2.0 + self.horizon_rad)
        }
    }

    /// Fractional row of `elevation` ([`Self::elevation`]'s inverse; the
    /// last row above `top_rad`).
    fn row(&self, elevation: f64) -> f64 {
        let h = self.horizon_rad;
        let v = if elevation >= h {
            0.5 + 0.5 * ((elevation - h) / (self.top_rad - h)).min(1.0).sqrt()
        } else {
            0.5 - 0.5 * ((h - elevation) / (PI / 2.0 + h)).sqrt()
        };
        v.clamp(0.0, 1.0) * (VIEW_ROWS - 1) as f64
    }
}

/// The direction at `elevation` and `azimuth` from the sun in `frame`.
fn direction(frame: &[DVec3; 3], elevation: f64, azimuth: f64) -> DVec3 {
    let [zenith, x, y] = *frame;
    (zenith * elevation.sin() + (x * azimuth.cos() + y * azimuth.sin()) * elevation.cos())
        .normalize()
}

/// Bilinear interpolation in the observer's table (row-major,
/// `column_count` wide) at fractional (row, column), each clamped to its
/// count.
fn bilinear(
    values: &[[Spectrum; 3]],
    (row, rows): (f64, usize),
    (column, column_count): (f64, usize),
) -> [Spectrum; 3] {
    let (i, fi) = optics::split(row, rows);
    let (k, fk) = optics::split(column, column_count);
    let mut out = [[0.0; NODES]; 3];
    for (di, wi) in [(0, 1.0 - fi), (1, fi)] {
        for (dk, wk) in [(0, 1.0 - fk), (1, fk)] {
            let texel = &values[(i + di) * column_count + k + dk];
            for (o, v) in out.iter_mut().zip(texel) {
                optics::add_scaled(o, wi * wk, v);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Renderer;
    use crate::Scene;

    /// The model of `renderer`'s scene and its light field, on the tables
    /// its atmosphere shares.
    fn model_and_field(renderer: &Renderer) -> (SkyModel, ModelField) {
        let model = renderer.sky_model();
        let field = ModelField::from_tables(Arc::clone(&model.tables), renderer.sun_direction);
        (model, field)
    }

    /// The luminance of a response at the model's nodes.
    fn luminance(model: &SkyModel, response: [f64; NODES]) -> f64 {
        (0..NODES)
            .map(|n| response[n] * model.xyz_weights[1][n])
            .sum()
    }

    /// The observer's table against the march it tabulates, at elevations
    /// about the horizon (where the sky's light drops by two orders of
    /// magnitude to the ground's), for an observer on the ground and one
    /// in orbit (horizon 20° below the horizontal).
    #[test]
    fn the_view_table_matches_its_march_about_the_horizon() {
        for name in ["sunset", "space"] {
            let renderer = Renderer::new(&Scene::preset(name).unwrap()).unwrap();
            let medium = &renderer.medium;
            let (model, field) = model_and_field(&renderer);
            let [zenith, x, y] = model.frame;
            // (exact, table) luminance per view.
            let mut pairs = Vec::new();
            for step in -20..=20 {
                // Half-degree steps about the horizon (its dip is
                // acos(R/r)), between the table's rows.
                let dip = (medium.planet_radius_m / renderer.observer_m.length()).acos();
                let elevation = -dip + (f64::from(step) + 0.25) * 0.5_f64.to_radians();
                for azimuth_deg in [30.0_f64, 90.0, 150.0] {
                    let dir = direction(&[zenith, x, y], elevation, azimuth_deg.to_radians());
                    let response = field.radiance(medium, renderer.observer_m, dir);
                    pairs.push((luminance(&model, response), model.xyz(dir)[1]));
                }
            }
            // Off by the view's own light, or by a thousandth of the
            // brightest where the light is far below it (the limb's top
            // from orbit, the sky's drop to the ground).
            let peak = pairs.iter().map(|p| p.0).fold(0.0, f64::max);
            let worst = pairs
                .iter()
                .map(|&(exact, table)| (table - exact).abs() / exact.max(1e-3 * peak))
                .fold(0.0, f64::max);
            // Bilinear interpolation between rows a fraction of a degree
            // apart at the horizon: a few per cent where the light changes
            // fastest.
            assert!(worst < 0.05, "{name}: table off its march by {worst}");
        }
    }

    /// With the sun below the horizon the ground is lit by the sky alone,
    /// so the model's ground below an observer on it must be the albedo
    /// over π times the cosine-weighted integral of the model's own sky
    /// (the path tracer's twilight is, to a thousandth: its ground reads
    /// 0.3003/π of its sky's integral over two 150 s renders, for an
    /// albedo of 0.3; `BENCHMARKS.md`, the preview). Between
    /// [`MS_ZENITHS`]' nodes 2° apart (−5.6°, −3.6°) the irradiance,
    /// interpolated geometrically, left the ground 2.6 % dark against it
    /// at −1° and 2.8 % at −4°; at [`E_ZENITHS`] nodes it reads 0.99–1.01
    /// from −1° to −6°.
    /// (Deeper, the ground drifts brighter than its sky, with nodes or
    /// between them alike: 1.017 at −7°, 1.028 at −8°, 1.038 at −12°.)
    #[test]
    fn the_ground_below_the_horizons_sun_is_lit_by_the_models_own_sky() {
        for elevation_deg in [-1.0, -2.0, -3.0, -3.5, -4.0, -4.5, -5.0, -6.0] {
            let mut scene = Scene::preset("twilight").unwrap();
            scene.sun.elevation_deg = elevation_deg;
            let albedo = scene.atmosphere.ground_albedo;
            let renderer = Renderer::new(&scene).unwrap();
            let (model, _) = model_and_field(&renderer);
            let frame = model.frame;
            // E = ∫ L μ dμ dφ over the upper hemisphere: midpoints in
            // μ² (uniform in the cosine-weighted measure) and in φ.
            let (rows, columns) = (200_u32, 96_u32);
            let mut irradiance = 0.0;
            for i in 0..rows {
                let mu = ((f64::from(i) + 0.5) / f64::from(rows)).sqrt();
                for j in 0..columns {
                    let azimuth = 2.0 * PI * (f64::from(j) + 0.5) / f64::from(columns);
                    let dir = direction(&frame, mu.asin(), azimuth);
                    irradiance += model.xyz(dir)[1];
                }
            }
            // Each cell holds π / (rows · columns) of the cosine measure.
            irradiance *= PI / f64::from(rows * columns);
            let ground = model.xyz(-frame[0])[1];
            let ratio = ground * PI / (albedo * irradiance);
            assert!(
                (ratio - 1.0).abs() < 0.01,
                "sun {elevation_deg}°: ground {ground} against its sky's {irradiance} (ratio {ratio})"
            );
        }
    }

    /// A view ray that ends on the ground within a few kilometres takes
    /// fewer steps ([`view_steps`]) and gives the light of the full march:
    /// over the rows below the horizon seen from the ground, at sunset on
    /// the Earth and on Mars and at midday, both marches' luminance within
    /// a ten-thousandth.
    #[test]
    fn short_view_rays_lose_nothing_to_their_fewer_steps() {
        for name in ["sunset", "mars-sunset", "midday"] {
            let renderer = Renderer::new(&Scene::preset(name).unwrap()).unwrap();
            let medium = &renderer.medium;
            let (model, field) = model_and_field(&renderer);
            let (mut shortened, mut worst) = (0, 0.0_f64);
            for row in 0..HORIZON_ROW {
                let elevation = model.rows.elevation(row as f64);
                for azimuth_deg in [0.0_f64, 5.0, 30.0, 90.0, 180.0] {
                    let dir = direction(&model.frame, elevation, azimuth_deg.to_radians());
                    let span = medium.span(renderer.observer_m, dir).unwrap();
                    let steps = view_steps(span.t_exit - span.t_enter);
                    if steps == VIEW_STEPS {
                        continue;
                    }
                    shortened += 1;
                    let full = luminance(
                        &model,
                        field.radiance_marched(medium, renderer.observer_m, dir, VIEW_STEPS),
                    );
                    let short = luminance(
                        &model,
                        field.radiance_marched(medium, renderer.observer_m, dir, steps),
                    );
                    worst = worst.max((short - full).abs() / full);
                }
            }
            assert!(
                shortened >= 5 * 20,
                "{name}: only {shortened} views shortened"
            );
            // 1.3·10⁻⁵ at worst (sunset).
            assert!(worst < 1e-4, "{name}: fewer steps off by {worst}");
        }
    }

    /// The observer's table about the sun at Mars sunset, where the dust's
    /// light scattered twice or more is an aureole a few degrees wide:
    /// between the table's columns (1–2° apart there) B, held over the aureole's
    /// shape, gives its march's light.
    #[test]
    fn the_view_table_holds_the_aureole_between_its_columns() {
        let renderer = Renderer::new(&Scene::preset("mars-sunset").unwrap()).unwrap();
        let (medium, sun) = (&renderer.medium, renderer.sun_direction);
        let (model, field) = model_and_field(&renderer);
        let sun_elevation = sun.dot(model.frame[0]).asin();
        let mut worst = 0.0_f64;
        for lift_deg in [0.5_f64, 3.0, 6.0] {
            for azimuth_deg in [2.9_f64, 4.4, 8.7, 14.5] {
                let elevation = sun_elevation + lift_deg.to_radians();
                let dir = direction(&model.frame, elevation, azimuth_deg.to_radians());
                let response = field.radiance(medium, renderer.observer_m, dir);
                let exact = luminance(&model, response);
                let table = model.xyz(dir)[1];
                worst = worst.max((table - exact).abs() / exact);
            }
        }
        // 0.7 % off at worst (2.7 % with 32 even columns); with B
        // interpolated as it is between the columns, 5.0 % (the aureole's
        // skirt is convex between them).
        assert!(worst < 0.015, "table off its march by {worst}");
    }

    /// A pixel that the horizon crosses holds its sliver of sky: from 2 m
    /// the horizon lies 0.03–0.05° below the horizontal, and beside the
    /// sun the sky just above it is many times brighter than the ground
    /// below. The image's pixel against a dense grid over the pixel (4 ×
    /// 4096 points): 0.1 % apart, where the ground alone reads 11–28 %
    /// less.
    #[test]
    fn a_pixel_the_horizon_crosses_holds_its_sliver_of_sky() {
        let mut scene = Scene::preset("mars-sunset").unwrap();
        (scene.render.width, scene.render.height) = (64, 32);
        let renderer = Renderer::new(&scene).unwrap();
        let model = renderer.sky_model();
        let camera = renderer.camera();
        let image = model.image(camera, 64, 32);
        let horizon = model.rows.horizon_rad.sin();
        let zenith = model.frame[0];
        let above =
            |x: f64, y: f64| camera.direction(x, y).unwrap().normalize().dot(zenith) > horizon;
        // The row the horizon crosses, at the sun's column and 20° beside it.
        let row = (0..32).find(|&y| above(0.5, f64::from(y)) != above(0.5, f64::from(y) + 1.0));
        let row = row.expect("the horizon crosses a row");
        let (sun_x, _) = camera.project(renderer.sun_direction).unwrap();
        for x in [sun_x.floor(), (sun_x + 64.0 / 18.0).floor()] {
            let (mut dense, mut ground, mut below) = (0.0, 0.0, 0);
            let n = 4096;
            for i in 0..4 {
                for j in 0..n {
                    let (fx, fy) = (
                        (f64::from(i) + 0.5) / 4.0,
                        (f64::from(j) + 0.5) / f64::from(n),
                    );
                    let dir = camera.direction(x + fx, f64::from(row) + fy).unwrap();
                    let y = model.xyz(dir)[1];
                    dense += y;
                    if !above(x + fx, f64::from(row) + fy) {
                        ground += y;
                        below += 1;
                    }
                }
            }
            dense /= f64::from(4 * n);
            ground /= f64::from(below);
            let pixel = image.pixels[row as usize * 64 + x as usize];
            let y = crate::spectrum::rec709_luminance(pixel.map(f64::from));
            assert!(
                dense > 1.1 * ground,
                "the sliver matters: {dense} against {ground}"
            );
            assert!(
                (y - dense).abs() < 0.005 * dense,
                "pixel {y}, dense grid {dense}"
            );
        }
    }

    /// A row's fan of marches gives what each direction's own march does
    /// (the view table's rows are marched as fans), from the ground at
    /// twilight and from orbit, above and below the horizon.
    #[test]
    fn a_fan_of_marches_matches_its_single_marches() {
        for name in ["twilight", "space"] {
            let renderer = Renderer::new(&Scene::preset(name).unwrap()).unwrap();
            let (medium, sun) = (&renderer.medium, renderer.sun_direction);
            let model = renderer.sky_model();
            let tables = Arc::clone(&model.tables);
            let field = ModelField::from_tables(Arc::clone(&tables), sun);
            let optics = field.optics(medium);
            for elevation_deg in [-60.0_f64, -21.0, -1.0, 0.5, 10.0, 80.0] {
                let dirs: Vec<DVec3> = (0..7)
                    .map(|k| {
                        let azimuth = PI * f64::from(k) / 6.0;
                        direction(&model.frame, elevation_deg.to_radians(), azimuth)
                    })
                    .collect();
                let sources = || Sources::all(&tables.ms, &tables.sky);
                let mut fan: Vec<Gathered> = dirs.iter().map(|_| Gathered::default()).collect();
                optics.march_fan(renderer.observer_m, &dirs, VIEW_STEPS, sources(), &mut fan);
                for (dir, g) in dirs.iter().zip(&fan) {
                    let one = optics.march(renderer.observer_m, *dir, VIEW_STEPS, sources());
                    let pairs = [
                        (one.rayleigh, g.rayleigh),
                        (one.aerosol, g.aerosol),
                        (one.isotropic, g.isotropic),
                        (one.scattering, g.scattering),
                    ];
                    for (a, b) in pairs {
                        for n in 0..NODES {
                            assert!(
                                (a[n] - b[n]).abs() <= 1e-9 * a[n].abs().max(1e-30),
                                "{name} at {elevation_deg}°: {} against {}",
                                b[n],
                                a[n]
                            );
                        }
                    }
                }
            }
        }
    }
}
