//! Values at scattered image points spread over every pixel of a frame.
//!
//! Algorithm: inside the given triangles (a triangulation of the points,
//! e.g. their Delaunay triangles), linear: each pixel takes the barycentric
//! blend of its triangle's three values, with the barycentric coordinates
//! and the tolerance (`INSIDE`, 100 machine epsilons) that SciPy's
//! `LinearNDInterpolator` uses, so both agree to rounding. Elsewhere, the
//! value of the nearest point, as SciPy's `NearestNDInterpolator`: each
//! row's squared distances to the points are the lower envelope of one
//! parabola per point, `(x − x_i)² + (y − y_i)²`, found in O(n) over the
//! points sorted by column (Felzenszwalb and Huttenlocher's distance
//! transform, with real-valued centres), so a pixel costs O(1) whatever the
//! number of points. Rows run in parallel (rayon); every pixel's value is
//! computed in the same order at any thread count.
//!
//! Frames and units: pixel coordinates, column x and row y, pixel centres at
//! integers; the output is (H, W) row-major f64.

use rayon::prelude::*;

use crate::error::{InvalidArgument, Result};

/// Barycentric coordinates down to minus this count a pixel as inside a
/// triangle (SciPy's `find_simplex` tolerance, 100 × f64's epsilon).
pub const INSIDE: f64 = 100.0 * f64::EPSILON;

/// The most pixels one frame may have (2^31): a larger size is refused, not allocated.
pub const MAX_PIXELS: usize = 1 << 31;

/// A triangle's barycentric map, as SciPy's `Delaunay.transform` holds it:
/// `c0, c1 = T (p − v2)`, `c2 = 1 − c0 − c1`.
struct Barycentric {
    t: [[f64; 2]; 2],
    origin: [f64; 2],
    values: [f64; 3],
    rows: (f64, f64),
}

impl Barycentric {
    /// `None` for a degenerate (zero-area) triangle, which covers no pixel.
    fn new(p: [[f64; 2]; 3], values: [f64; 3]) -> Option<Self> {
        let (a, b, c, d) = (p[0][0] - p[2][0], p[1][0] - p[2][0], p[0][1] - p[2][1], p[1][1] - p[2][1]);
        let det = a * d - b * c;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let t = [[d / det, -b / det], [-c / det, a / det]];
        let ys = [p[0][1], p[1][1], p[2][1]];
        Some(Self { t, origin: p[2], values, rows: (ys.iter().cloned().fold(f64::INFINITY, f64::min), ys.iter().cloned().fold(f64::NEG_INFINITY, f64::max)) })
    }

    fn coordinates(&self, x: f64, y: f64) -> [f64; 3] {
        let (dx, dy) = (x - self.origin[0], y - self.origin[1]);
        let c0 = self.t[0][0] * dx + self.t[0][1] * dy;
        let c1 = self.t[1][0] * dx + self.t[1][1] * dy;
        [c0, c1, 1.0 - c0 - c1]
    }

    /// The columns of row `y` this triangle may cover, widened by a pixel
    /// so that rounding never hides one; each is then checked exactly.
    fn columns(&self, y: f64, width: usize) -> std::ops::Range<usize> {
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        let dy = y - self.origin[1];
        // c_k(x) = slope_k x + offset_k along the row.
        let slopes = [self.t[0][0], self.t[1][0], -self.t[0][0] - self.t[1][0]];
        let c0 = self.t[0][1] * dy - self.t[0][0] * self.origin[0];
        let c1 = self.t[1][1] * dy - self.t[1][0] * self.origin[0];
        let offsets = [c0, c1, 1.0 - c0 - c1];
        for (slope, offset) in slopes.into_iter().zip(offsets) {
            if slope > 0.0 {
                lo = lo.max((-INSIDE - offset) / slope);
            } else if slope < 0.0 {
                hi = hi.min((-INSIDE - offset) / slope);
            } else if offset < -INSIDE - 1e-9 {
                return 0..0;
            }
        }
        if !(lo <= hi) {
            return 0..0;
        }
        let first = (lo.floor() - 1.0).max(0.0);
        let last = (hi.ceil() + 1.0).min(width as f64 - 1.0);
        if first > last {
            return 0..0;
        }
        first as usize..last as usize + 1
    }
}

/// The values (H × W, row-major) of `values` at `points` (column, row)
/// spread over an (H, W) frame: linear over `triangles` (indices into
/// `points`), the nearest point's value elsewhere (module header).
pub fn spread(points: &[[f64; 2]], values: &[f64], triangles: &[[u32; 3]], size: [usize; 2]) -> Result<Vec<f64>> {
    let [height, width] = size;
    if height == 0 || width == 0 || height.checked_mul(width).is_none_or(|n| n > MAX_PIXELS) {
        return Err(InvalidArgument::new("size", format!("expected (H, W) >= 1 with at most {MAX_PIXELS} pixels, got ({height}, {width})")));
    }
    if points.is_empty() || values.len() != points.len() {
        return Err(InvalidArgument::new("values", format!("expected one value for each of at least 1 point, got {} values for {} points", values.len(), points.len())));
    }
    if !points.iter().flatten().chain(values).all(|v| v.is_finite()) {
        return Err(InvalidArgument::new("points", "expected finite positions and values"));
    }
    if let Some(bad) = triangles.iter().flatten().find(|&&i| i as usize >= points.len()) {
        return Err(InvalidArgument::new("triangles", format!("expected indices below the {} points, got {bad}", points.len())));
    }
    let triangles: Vec<Barycentric> = triangles
        .iter()
        .filter_map(|t| Barycentric::new(t.map(|i| points[i as usize]), t.map(|i| values[i as usize])))
        .collect();
    let mut by_column: Vec<usize> = (0..points.len()).collect();
    by_column.sort_by(|&a, &b| points[a][0].total_cmp(&points[b][0]).then(a.cmp(&b)));
    let mut out = vec![0.0; height * width];
    out.par_chunks_mut(width).enumerate().for_each_init(
        || (vec![false; width], Vec::new(), Vec::new()),
        |(filled, envelope, bounds), (row, line)| {
            let y = row as f64;
            filled.fill(false);
            for triangle in triangles.iter().filter(|t| t.rows.0 - 1.0 <= y && y <= t.rows.1 + 1.0) {
                for x in triangle.columns(y, width) {
                    if filled[x] {
                        continue;
                    }
                    let c = triangle.coordinates(x as f64, y);
                    if c.iter().all(|&v| v >= -INSIDE) {
                        line[x] = c[0] * triangle.values[0] + c[1] * triangle.values[1] + c[2] * triangle.values[2];
                        filled[x] = true;
                    }
                }
            }
            if filled.iter().all(|&f| f) {
                return;
            }
            lower_envelope(points, &by_column, y, envelope, bounds);
            let mut k = 0;
            for (x, value) in line.iter_mut().enumerate() {
                let x = x as f64;
                while k + 1 < envelope.len() && bounds[k + 1] < x {
                    k += 1;
                }
                if !filled[x as usize] {
                    *value = values[envelope[k]];
                }
            }
        },
    );
    Ok(out)
}

/// The points nearest along row `y`: `envelope` gets, left to right, the
/// points whose parabola `(x − x_i)² + (y − y_i)²` is lowest somewhere on
/// the row, and `bounds[k]` the column where the k-th takes over
/// (−∞ for the first). `by_column`: the points' indices sorted by column.
fn lower_envelope(points: &[[f64; 2]], by_column: &[usize], y: f64, envelope: &mut Vec<usize>, bounds: &mut Vec<f64>) {
    envelope.clear();
    bounds.clear();
    let height = |i: usize| (y - points[i][1]) * (y - points[i][1]);
    for &i in by_column {
        let (xi, hi) = (points[i][0], height(i));
        loop {
            let Some(&j) = envelope.last() else {
                envelope.push(i);
                bounds.push(f64::NEG_INFINITY);
                break;
            };
            let (xj, hj) = (points[j][0], height(j));
            if xi == xj {
                if hi < hj {  // the same column, nearer: it replaces the last
                    envelope.pop();
                    bounds.pop();
                    continue;
                }
                break;  // the same column, no nearer: never lowest
            }
            // Where the two parabolas meet: i is lower to the right of it.
            let meet = ((hi + xi * xi) - (hj + xj * xj)) / (2.0 * (xi - xj));
            if meet <= *bounds.last().unwrap() {
                envelope.pop();
                bounds.pop();
                continue;
            }
            envelope.push(i);
            bounds.push(meet);
            break;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Every pixel as the module header defines it, by brute force: the
    /// first triangle whose barycentric coordinates hold it, else the
    /// nearest point (of equally near ones either may be taken: the cases
    /// below have no ties).
    fn brute(points: &[[f64; 2]], values: &[f64], triangles: &[[u32; 3]], size: [usize; 2]) -> (Vec<f64>, Vec<bool>) {
        let [h, w] = size;
        let tris: Vec<Barycentric> = triangles.iter().filter_map(|t| Barycentric::new(t.map(|i| points[i as usize]), t.map(|i| values[i as usize]))).collect();
        let mut out = vec![0.0; h * w];
        let mut inside = vec![false; h * w];
        for row in 0..h {
            for col in 0..w {
                let (x, y) = (col as f64, row as f64);
                if let Some(t) = tris.iter().find(|t| t.coordinates(x, y).iter().all(|&c| c >= -INSIDE)) {
                    let c = t.coordinates(x, y);
                    out[row * w + col] = c[0] * t.values[0] + c[1] * t.values[1] + c[2] * t.values[2];
                    inside[row * w + col] = true;
                } else {
                    let d = |p: &[f64; 2]| (p[0] - x).powi(2) + (p[1] - y).powi(2);
                    let best = (0..points.len()).min_by(|&a, &b| d(&points[a]).total_cmp(&d(&points[b]))).unwrap();
                    out[row * w + col] = values[best];
                }
            }
        }
        (out, inside)
    }

    /// A jittered grid of points, split into two triangles per cell.
    fn jittered(cols: usize, rows: usize, jitter: &[f64], spacing: f64, offset: [f64; 2]) -> (Vec<[f64; 2]>, Vec<[u32; 3]>) {
        let points = (0..rows * cols)
            .map(|k| [offset[0] + (k % cols) as f64 * spacing + jitter[2 * k], offset[1] + (k / cols) as f64 * spacing + jitter[2 * k + 1]])
            .collect();
        let mut triangles = Vec::new();
        for r in 0..rows - 1 {
            for c in 0..cols - 1 {
                let k = (r * cols + c) as u32;
                let (right, down) = (k + 1, k + cols as u32);
                triangles.push([k, right, down]);
                triangles.push([right, down + 1, down]);
            }
        }
        (points, triangles)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        /// Agrees with brute force: linear inside the triangles, the nearest point outside.
        #[test]
        fn agrees_with_brute_force(jitter in prop::collection::vec(-2.5f64..2.5, 2 * 16), values in prop::collection::vec(-5.0f64..5.0, 16),
                                   offset in (3.0f64..12.0, 2.0f64..9.0)) {
            let (points, triangles) = jittered(4, 4, &jitter, 7.0, [offset.0, offset.1]);
            let size = [40, 45];
            let fast = spread(&points, &values, &triangles, size).unwrap();
            let (slow, _) = brute(&points, &values, &triangles, size);
            for (a, b) in fast.iter().zip(&slow) {
                prop_assert!((a - b).abs() <= 1e-9, "{a} against {b}");
            }
        }

        /// A linear function of position comes back exactly inside the triangles.
        #[test]
        fn linear_functions_come_back(jitter in prop::collection::vec(-2.5f64..2.5, 2 * 25), a in -3.0f64..3.0, b in -3.0f64..3.0, c in -10.0f64..10.0) {
            let (points, triangles) = jittered(5, 5, &jitter, 6.0, [4.0, 5.0]);
            let values: Vec<f64> = points.iter().map(|p| a * p[0] + b * p[1] + c).collect();
            let size = [36, 38];
            let fast = spread(&points, &values, &triangles, size).unwrap();
            let (_, inside) = brute(&points, &values, &triangles, size);
            for (k, (&v, &i)) in fast.iter().zip(&inside).enumerate() {
                if i {
                    let (x, y) = ((k % size[1]) as f64, (k / size[1]) as f64);
                    prop_assert!((v - (a * x + b * y + c)).abs() <= 1e-9);
                }
            }
        }
    }

    /// Without triangles every pixel takes its nearest point, also where
    /// points share a column or sit outside the frame.
    #[test]
    fn nearest_without_triangles() {
        let points = [[2.3, 3.1], [2.3, 9.2], [-4.1, 1.3], [14.2, 6.6], [7.0, 20.4], [7.0, -3.3]];
        let values = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let size = [12, 13];
        assert_eq!(spread(&points, &values, &[], size).unwrap(), brute(&points, &values, &[], size).0);
    }

    #[test]
    fn refuses_bad_input() {
        let p = [[0.0, 0.0], [5.0, 0.0], [0.0, 5.0]];
        assert!(spread(&p, &[1.0, 2.0], &[], [4, 4]).is_err());
        assert!(spread(&p, &[1.0, 2.0, f64::NAN], &[], [4, 4]).is_err());
        assert!(spread(&p, &[1.0, 2.0, 3.0], &[[0, 1, 3]], [4, 4]).is_err());
        assert!(spread(&p, &[1.0, 2.0, 3.0], &[], [0, 4]).is_err());
        assert!(spread(&p, &[1.0, 2.0, 3.0], &[], [usize::MAX / 2, 4]).is_err());  // overflows H × W
        assert!(spread(&p, &[1.0, 2.0, 3.0], &[], [1 << 20, 1 << 12]).is_err());  // over MAX_PIXELS
        assert!(spread(&[], &[], &[], [4, 4]).is_err());
    }
}
