//! Bounding-volume hierarchy over a triangle mesh, and ray casting.
//!
//! Layout: nodes in depth-first preorder; an inner node's left child is the
//! next node and its right child is at `first`; a leaf holds triangles
//! `order[first .. first + count]`. Boxes are axis-aligned, world units.
//!
//! Two builds share one refit:
//! - `Bvh::build`: any mesh; recursive median split of triangle centroids along
//!   the widest axis, at most `LEAF_SIZE` triangles a leaf. O(F log F).
//! - `Bvh::for_grid`: the `grid × grid` surface mesh of `mesh::grid_triangles`;
//!   recursive halving of the rectangle of grid cells, two cells a leaf. O(F),
//!   no geometry needed: the topology of a deforming grid never changes, so the
//!   tree is built once and only `refit` (O(F), no sorting) runs per frame. A
//!   smooth deformation keeps neighbouring cells close, so the refitted boxes
//!   stay tight.
//!
//! Rays are vertical, straight down −z: the orthographic camera's, or a
//! perspective camera's in the space where its rays are (`View::warp`: the
//! tree is built over the warped mesh, and a hit's warped height maps back to
//! its depth, `View::depth`). A ray hits
//! the highest triangle (largest z) over its (x, y), found by traversing
//! nearer boxes first and pruning boxes entirely below the best hit so far.
//! `depth_into` casts the rays of a tile of 8×8 pixels as one packet (for an
//! orthographic camera a packet is bounded by an xy box) and tests each leaf
//! triangle only against the tile's pixel centres inside its bounds; the
//! coverage test runs in pixel space (`View::pixel_vertex`), like the
//! rasteriser's.

use rayon::prelude::*;

use crate::geometry::{ceil_fast, check_mesh, floor_fast, vertical_hit, TriangleSetup, View};
use crate::error::Result;

pub const LEAF_SIZE: usize = 4;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Node {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
    pub first: u32,
    /// Number of triangles of a leaf; 0 for an inner node.
    pub count: u32,
}

#[derive(Clone, Debug, Default)]
pub struct Bvh {
    pub nodes: Vec<Node>,
    pub order: Vec<u32>,
}

/// The first hit of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub z: f32,
    pub triangle: u32,
    /// Barycentric weights of the triangle's three vertices.
    pub weights: [f32; 3],
}

impl Bvh {
    /// Median-split build for any mesh, then a refit to `vertices`.
    pub fn build(vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> Self {
        let centroid = |t: &[u32; 3], axis: usize| -> f32 { t.iter().map(|&k| vertices[k as usize][axis]).sum::<f32>() };
        let mut bvh = Bvh { nodes: Vec::with_capacity(2 * triangles.len() / LEAF_SIZE + 1), order: (0..triangles.len() as u32).collect() };
        // Explicit stack of (node index, range); children are created in preorder.
        fn split(bvh: &mut Bvh, start: usize, end: usize, key: &dyn Fn(u32, usize) -> f32) {
            let node = bvh.nodes.len();
            bvh.nodes.push(Node::default());
            if end - start <= LEAF_SIZE {
                bvh.nodes[node] = Node { first: start as u32, count: (end - start) as u32, ..Node::default() };
                return;
            }
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for &t in &bvh.order[start..end] {
                for a in 0..3 {
                    let c = key(t, a);
                    lo[a] = lo[a].min(c);
                    hi[a] = hi[a].max(c);
                }
            }
            let axis = (0..3).max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b]))).unwrap_or(0);
            let mid = (start + end) / 2;
            bvh.order[start..end].select_nth_unstable_by(mid - start, |&p, &q| key(p, axis).total_cmp(&key(q, axis)).then(p.cmp(&q)));
            split(bvh, start, mid, key);
            let right = bvh.nodes.len() as u32;
            split(bvh, mid, end, key);
            bvh.nodes[node] = Node { first: right, count: 0, ..Node::default() };
        }
        let key = |t: u32, axis: usize| centroid(&triangles[t as usize], axis);
        if !triangles.is_empty() {
            split(&mut bvh, 0, triangles.len(), &key);
        }
        bvh.refit(vertices, triangles);
        bvh
    }

    /// Topology-only build for the `grid × grid` surface mesh (`mesh::grid_triangles`
    /// order: cell (cy, cx) holds triangles 2(cy(grid − 1) + cx) and the next).
    /// Call `refit` before casting.
    pub fn for_grid(grid: usize) -> Self {
        let cells = grid.saturating_sub(1);
        let mut bvh = Bvh { nodes: Vec::with_capacity(cells * cells + 1), order: Vec::with_capacity(2 * cells * cells) };
        fn split(bvh: &mut Bvh, cells: usize, x0: usize, x1: usize, y0: usize, y1: usize) {
            let node = bvh.nodes.len();
            bvh.nodes.push(Node::default());
            if (x1 - x0) * (y1 - y0) <= 2 {
                let first = bvh.order.len() as u32;
                for cy in y0..y1 {
                    for cx in x0..x1 {
                        let t = 2 * (cy * cells + cx) as u32;
                        bvh.order.extend_from_slice(&[t, t + 1]);
                    }
                }
                bvh.nodes[node] = Node { first, count: bvh.order.len() as u32 - first, ..Node::default() };
                return;
            }
            if x1 - x0 >= y1 - y0 {
                let xm = (x0 + x1) / 2;
                split(bvh, cells, x0, xm, y0, y1);
                let right = bvh.nodes.len() as u32;
                split(bvh, cells, xm, x1, y0, y1);
                bvh.nodes[node] = Node { first: right, count: 0, ..Node::default() };
            } else {
                let ym = (y0 + y1) / 2;
                split(bvh, cells, x0, x1, y0, ym);
                let right = bvh.nodes.len() as u32;
                split(bvh, cells, x0, x1, ym, y1);
                bvh.nodes[node] = Node { first: right, count: 0, ..Node::default() };
            }
        }
        if cells > 0 {
            split(&mut bvh, cells, 0, cells, 0, cells);
        }
        bvh
    }

    /// Recompute every box for new vertex positions (same topology), children
    /// before parents: preorder reversed.
    pub fn refit(&mut self, vertices: &[[f32; 3]], triangles: &[[u32; 3]]) {
        for i in (0..self.nodes.len()).rev() {
            let node = self.nodes[i];
            let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
            if node.count > 0 {
                for &t in &self.order[node.first as usize..(node.first + node.count) as usize] {
                    for &k in &triangles[t as usize] {
                        let v = vertices[k as usize];
                        for a in 0..3 {
                            lo[a] = lo[a].min(v[a]);
                            hi[a] = hi[a].max(v[a]);
                        }
                    }
                }
            } else {
                let (l, r) = (self.nodes[i + 1], self.nodes[node.first as usize]);
                for a in 0..3 {
                    lo[a] = l.lo[a].min(r.lo[a]);
                    hi[a] = l.hi[a].max(r.hi[a]);
                }
            }
            self.nodes[i].lo = lo;
            self.nodes[i].hi = hi;
        }
    }

    /// The highest triangle over (x, y) with z ≤ `z_max`, if any.
    pub fn cast_down(&self, vertices: &[[f32; 3]], triangles: &[[u32; 3]], x: f32, y: f32, z_max: f32) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut best_z = f32::NEG_INFINITY;
        let mut stack = [0u32; 64];
        let mut top = 0;
        if self.nodes.is_empty() {
            return None;
        }
        stack[0] = 0;
        top += 1;
        while top > 0 {
            top -= 1;
            let index = stack[top] as usize;
            let node = &self.nodes[index];
            if x < node.lo[0] || x > node.hi[0] || y < node.lo[1] || y > node.hi[1] || node.hi[2] < best_z || node.lo[2] > z_max {
                continue;
            }
            if node.count > 0 {
                for &t in &self.order[node.first as usize..(node.first + node.count) as usize] {
                    let [a, b, c] = triangles[t as usize];
                    let (a, b, c) = (vertices[a as usize], vertices[b as usize], vertices[c as usize]);
                    if let Some((z, weights)) = vertical_hit(a, b, c, x, y) {
                        if z > best_z && z <= z_max {
                            best_z = z;
                            best = Some(Hit { z, triangle: t, weights });
                        }
                    }
                }
            } else {
                // Push the lower child first so the higher one is visited first.
                let (l, r) = (index + 1, node.first as usize);
                let (near, far) = if self.nodes[l].hi[2] >= self.nodes[r].hi[2] { (l, r) } else { (r, l) };
                if top + 2 > stack.len() {
                    // Deeper than any balanced tree we build; fall back to a full scan.
                    return brute_force_hit(vertices, triangles, x, y, z_max);
                }
                stack[top] = far as u32;
                stack[top + 1] = near as u32;
                top += 2;
            }
        }
        best
    }

    /// Depth image (`View::depth`) of the first hit at each pixel centre, NaN on a
    /// miss, into `depth` (H·W, row-major); `vertices` warped (`View::warp`),
    /// as the tree was built over them.
    pub fn depth_into(&self, vertices: &[[f32; 3]], triangles: &[[u32; 3]], view: &View, depth: &mut [f32]) {
        self.depth_band(vertices, triangles, view, 0, depth);
    }

    /// Depth of the pixel rows `row0 ..` that `band` (whole rows) holds.
    fn depth_band(&self, vertices: &[[f32; 3]], triangles: &[[u32; 3]], view: &View, row0: usize, band: &mut [f32]) {
        let width = view.width;
        let rows = band.len() / width;
        band.fill(f32::NEG_INFINITY);
        for r in (0..rows).step_by(TILE) {
            for c in (0..width).step_by(TILE) {
                let tile = Tile { row0, rows: r..(r + TILE).min(rows), cols: c..(c + TILE).min(width) };
                self.cast_tile(vertices, triangles, view, &tile, band);
            }
        }
        for d in band.iter_mut() {
            *d = if *d == f32::NEG_INFINITY { f32::NAN } else { view.depth(*d) };
        }
    }

    /// Cast the rays of one tile of pixel centres as a packet: one traversal
    /// bounded by the tile's xy box; each triangle of a visited leaf is tested
    /// only against the tile's pixels inside its xy bounds. `band` holds the
    /// best z so far per pixel (−∞: no hit).
    fn cast_tile(&self, vertices: &[[f32; 3]], triangles: &[[u32; 3]], view: &View, tile: &Tile, band: &mut [f32]) {
        if self.nodes.is_empty() {
            return;
        }
        let width = view.width;
        let centre = |r: usize, c: usize| view.world((tile.row0 + r) as f32 + 0.5, c as f32 + 0.5);
        let (xa, ya) = centre(tile.rows.start, tile.cols.start);
        let (xb, yb) = centre(tile.rows.end - 1, tile.cols.end - 1);
        let (x_lo, x_hi, y_lo, y_hi) = (xa.min(xb), xa.max(xb), ya.min(yb), ya.max(yb));
        // Lowest best hit over the tile: boxes entirely below it cannot matter.
        let mut floor_z = f32::NEG_INFINITY;
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let index = stack[top] as usize;
            let node = &self.nodes[index];
            if node.hi[0] < x_lo || node.lo[0] > x_hi || node.hi[1] < y_lo || node.lo[1] > y_hi || node.hi[2] < floor_z || node.lo[2] > view.z_max() {
                continue;
            }
            if node.count == 0 {
                let (l, r) = (index + 1, node.first as usize);
                let (near, far) = if self.nodes[l].hi[2] >= self.nodes[r].hi[2] { (l, r) } else { (r, l) };
                stack[top] = far as u32;
                stack[top + 1] = near as u32;
                top += 2;
                continue;
            }
            let mut updated = false;
            for &t in &self.order[node.first as usize..(node.first + node.count) as usize] {
                let [a, b, c] = triangles[t as usize].map(|k| view.screen(vertices[k as usize], 1.0));
                // Pixel rows/columns whose centres can lie in the triangle's bounds;
                // a small margin absorbs rounding, vertical_hit decides exactly.
                let (c0, c1) = (a[0].min(b[0]).min(c[0]), a[0].max(b[0]).max(c[0]));
                let (r0, r1) = (a[1].min(b[1]).min(c[1]), a[1].max(b[1]).max(c[1]));
                let span = |lo: f32, hi: f32, range: &std::ops::Range<usize>, offset: usize| {
                    let first = (ceil_fast(lo - 0.5 - MARGIN).max(0.0) as usize).max(range.start + offset);
                    let last = (floor_fast(hi - 0.5 + MARGIN).max(-1.0) as isize).min((range.end + offset) as isize - 1);
                    (first, last)
                };
                let (row_first, row_last) = span(r0, r1, &tile.rows, tile.row0);
                let (col_first, col_last) = span(c0, c1, &tile.cols, 0);
                if row_first as isize > row_last || col_first as isize > col_last {
                    continue;
                }
                let Some(setup) = TriangleSetup::new(a, b, c) else { continue };
                for row in row_first as isize..=row_last {
                    for col in col_first as isize..=col_last {
                        let (row, col) = (row as usize, col as usize);
                        if let Some((z, _)) = setup.hit(col as f32 + 0.5, row as f32 + 0.5) {
                            let best = &mut band[(row - tile.row0) * width + col];
                            if z > *best && z <= view.z_max() {
                                *best = z;
                                updated = true;
                            }
                        }
                    }
                }
            }
            if updated {
                floor_z = tile.rows.clone().flat_map(|r| tile.cols.clone().map(move |c| (r, c))).map(|(r, c)| band[r * width + c]).fold(f32::INFINITY, f32::min);
            }
        }
    }
}

/// Rays are cast in tiles of TILE × TILE pixels.
pub const TILE: usize = 8;
/// Slack, in pixels, of a triangle's pixel bounds.
const MARGIN: f32 = 1e-3;

struct Tile {
    row0: usize,
    rows: std::ops::Range<usize>,
    cols: std::ops::Range<usize>,
}

/// The reference answer: test every triangle.
pub fn brute_force_hit(vertices: &[[f32; 3]], triangles: &[[u32; 3]], x: f32, y: f32, z_max: f32) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    for (t, tri) in triangles.iter().enumerate() {
        let (a, b, c) = (vertices[tri[0] as usize], vertices[tri[1] as usize], vertices[tri[2] as usize]);
        if let Some((z, weights)) = vertical_hit(a, b, c, x, y) {
            if z <= z_max && best.is_none_or(|h| z > h.z) {
                best = Some(Hit { z, triangle: t as u32, weights });
            }
        }
    }
    best
}

/// Ray-cast depth of any mesh, rows in parallel: (H·W) row-major, NaN on a miss.
pub fn raycast_depth(vertices: &[[f32; 3]], triangles: &[[u32; 3]], view: &View) -> Result<Vec<f32>> {
    check_mesh(vertices, triangles)?;
    view.check_in_front(vertices)?;
    let warped: std::borrow::Cow<[[f32; 3]]> = match view.pinhole {
        None => vertices.into(),
        Some(_) => vertices.iter().map(|&v| view.warp(v)).collect::<Vec<_>>().into(),
    };
    let vertices = &warped[..];
    let bvh = Bvh::build(vertices, triangles);
    let mut depth = vec![0.0; view.height * view.width];
    depth
        .par_chunks_mut(TILE * view.width)
        .enumerate()
        .for_each(|(k, band)| bvh.depth_band(vertices, triangles, view, k * TILE, band));
    Ok(depth)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::CAMERA_Z;
    use crate::mesh::grid_triangles;
    use crate::params::SurfaceConfig;
    use crate::synthesis::synthesize;
    use proptest::prelude::*;

    fn as_vertices(flat: &[f32]) -> Vec<[f32; 3]> {
        flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
    }

    fn as_triangles(flat: &[u32]) -> Vec<[u32; 3]> {
        flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
    }

    fn same_hit(a: Option<Hit>, b: Option<Hit>) -> bool {
        match (a, b) {
            (None, None) => true,
            (Some(a), Some(b)) => a.z == b.z,
            _ => false,
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn bvh_hits_equal_brute_force_hits_on_random_soups(
            coords in prop::collection::vec(-1.0f32..1.0, 9..600),
            rays in prop::collection::vec((-1.1f32..1.1, -1.1f32..1.1), 1..64),
            z_max in -0.5f32..2.0,
        ) {
            let vertices: Vec<[f32; 3]> = coords.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            let triangles: Vec<[u32; 3]> = (0..vertices.len() as u32 / 3).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
            let bvh = Bvh::build(&vertices, &triangles);
            for &(x, y) in &rays {
                let fast = bvh.cast_down(&vertices, &triangles, x, y, z_max);
                let slow = brute_force_hit(&vertices, &triangles, x, y, z_max);
                prop_assert!(same_hit(fast, slow), "ray ({x}, {y}): {fast:?} vs {slow:?}");
            }
        }

        #[test]
        fn grid_bvh_hits_equal_brute_force_on_deformed_surfaces(seed in 0u64..1000, grid in 2usize..24) {
            let params = SurfaceConfig::default().sample(seed).unwrap();
            let vertices = as_vertices(&synthesize(&params, 1, grid).unwrap());
            let triangles = as_triangles(&grid_triangles(grid as i64).unwrap());
            let mut bvh = Bvh::for_grid(grid);
            bvh.refit(&vertices, &triangles);
            let mut order = bvh.order.clone();
            order.sort_unstable();
            prop_assert_eq!(order, (0..triangles.len() as u32).collect::<Vec<_>>());
            for k in 0..50 {
                let (x, y) = (-1.0 + 2.0 * ((k * 7) % 50) as f32 / 49.0, -1.0 + 2.0 * k as f32 / 49.0);
                let fast = bvh.cast_down(&vertices, &triangles, x, y, CAMERA_Z);
                let slow = brute_force_hit(&vertices, &triangles, x, y, CAMERA_Z);
                prop_assert!(same_hit(fast, slow));
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        #[test]
        fn packet_depth_equals_brute_force_per_pixel(seed in 0u64..1000, grid in 2usize..40, h in 1usize..30, w in 1usize..30) {
            let params = SurfaceConfig::default().sample(seed).unwrap();
            let vertices = as_vertices(&synthesize(&params, 1, grid).unwrap());
            let triangles = as_triangles(&grid_triangles(grid as i64).unwrap());
            let view = View::new(h, w, [-1.1, -0.9, 0.8, 1.05], CAMERA_Z).unwrap();
            let depth = raycast_depth(&vertices, &triangles, &view).unwrap();
            let pixel_space: Vec<[f32; 3]> = vertices.iter().map(|&v| view.pixel_vertex(v, 1.0)).collect();
            for i in 0..h {
                for j in 0..w {
                    let hit = brute_force_hit(&pixel_space, &triangles, j as f32 + 0.5, i as f32 + 0.5, CAMERA_Z);
                    let expected = hit.map_or(f32::NAN, |hit| CAMERA_Z - hit.z);
                    let got = depth[i * w + j];
                    prop_assert!(got == expected || (got.is_nan() && expected.is_nan()), "({i},{j}): {got} vs {expected}");
                }
            }
        }
    }

    /// The nearest hit along the ray from `origin` in `direction` of any
    /// triangle (Möller–Trumbore, f64): the ray parameter t > 0.
    fn nearest_along(vertices: &[[f32; 3]], triangles: &[[u32; 3]], origin: [f64; 3], direction: [f64; 3]) -> Option<f64> {
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let cross = |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let mut best: Option<f64> = None;
        for tri in triangles {
            let [a, b, c] = tri.map(|k| vertices[k as usize].map(f64::from));
            let (e1, e2) = (sub(b, a), sub(c, a));
            let p = cross(direction, e2);
            let det = dot(e1, p);
            if det.abs() < 1e-14 {
                continue;
            }
            let s = sub(origin, a);
            let u = dot(s, p) / det;
            let q = cross(s, e1);
            let v = dot(direction, q) / det;
            let t = dot(e2, q) / det;
            if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 && best.is_none_or(|b| t < b) {
                best = Some(t);
            }
        }
        best
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn perspective_depth_equals_casting_each_ray_from_the_pinhole(
            waves in prop::collection::vec((0.5f32..3.0, 0.5f32..3.0, 0.0f32..6.3, 0.0f32..0.06), 1..4),
            pinhole in (-0.6f32..0.6, -0.6f32..0.6),
            camera_z in 0.9f32..4.0,
            (h, w) in (1usize..24, 1usize..24),
        ) {
            // A smooth heightfield (slopes below 0.6, no self-occlusion) over [-2, 2]², seen through a window inside it.
            let grid = 49;
            let height = |x: f32, y: f32| waves.iter().map(|&(fx, fy, phase, a)| a * (fx * x + fy * y + phase).sin()).sum::<f32>();
            let vertices: Vec<[f32; 3]> = (0..grid * grid).map(|k| {
                let (x, y) = (-2.0 + 4.0 * (k % grid) as f32 / (grid - 1) as f32, -2.0 + 4.0 * (k / grid) as f32 / (grid - 1) as f32);
                [x, y, height(x, y)]
            }).collect();
            let triangles = as_triangles(&grid_triangles(grid as i64).unwrap());
            let view = View::new(h, w, [-0.7, -0.6, 0.6, 0.7], camera_z).unwrap().with_pinhole([pinhole.0, pinhole.1]).unwrap();
            let depth = raycast_depth(&vertices, &triangles, &view).unwrap();
            let origin = [f64::from(pinhole.0), f64::from(pinhole.1), f64::from(camera_z)];
            for i in 0..h {
                for j in 0..w {
                    // The pixel's ray passes through its (x, y) on the plane z = 0.
                    let (x, y) = view.world(i as f32 + 0.5, j as f32 + 0.5);
                    let direction = [f64::from(x) - origin[0], f64::from(y) - origin[1], -origin[2]];
                    let t = nearest_along(&vertices, &triangles, origin, direction).expect("every ray meets the heightfield");
                    let expected = t * origin[2];
                    let got = f64::from(depth[i * w + j]);
                    prop_assert!((got - expected).abs() <= 1e-5 * expected, "({i},{j}): {got} vs {expected}");
                }
            }
        }
    }

    #[test]
    fn a_point_behind_the_pinhole_is_refused() {
        let view = View::new(4, 4, [-1.0, -1.0, 1.0, 1.0], 1.5).unwrap().with_pinhole([0.0, 0.0]).unwrap();
        let err = raycast_depth(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 2.0]], &[[0, 1, 2]], &view).unwrap_err();
        assert_eq!(err.name, "vertices");
    }

    #[test]
    fn tilted_plane_depth_is_exact() {
        // z = 0.3x − 0.2y + 0.1 tessellated by a grid: planar, so exact up to float error.
        let grid = 17;
        let mut vertices = Vec::new();
        for jy in 0..grid {
            for jx in 0..grid {
                let (x, y) = (-1.0 + 2.0 * jx as f32 / 16.0, -1.0 + 2.0 * jy as f32 / 16.0);
                vertices.push([x, y, 0.3 * x - 0.2 * y + 0.1]);
            }
        }
        let triangles = as_triangles(&grid_triangles(grid as i64).unwrap());
        let view = View::new(20, 30, [-0.9, -0.8, 0.9, 0.8], CAMERA_Z).unwrap();
        let depth = raycast_depth(&vertices, &triangles, &view).unwrap();
        for i in 0..20 {
            for j in 0..30 {
                let (x, y) = view.world(i as f32 + 0.5, j as f32 + 0.5);
                let expected = CAMERA_Z - (0.3 * x - 0.2 * y + 0.1);
                assert!((depth[i * 30 + j] - expected).abs() < 1e-5);
            }
        }
    }

    #[test]
    fn sphere_cap_depth_is_exact_to_tessellation() {
        // Vertices on the sphere x² + y² + z² = 4; a chord's sagitta bounds the error.
        let (grid, r) = (65usize, 2.0f32);
        let h = 1.0 / (grid - 1) as f32; // vertex spacing over [-0.5, 0.5]
        let mut vertices = Vec::new();
        for jy in 0..grid {
            for jx in 0..grid {
                let (x, y) = (-0.5 + jx as f32 * h, -0.5 + jy as f32 * h);
                vertices.push([x, y, (r * r - x * x - y * y).sqrt() - r]);
            }
        }
        let triangles = as_triangles(&grid_triangles(grid as i64).unwrap());
        let view = View::new(32, 32, [-0.4, -0.4, 0.4, 0.4], CAMERA_Z).unwrap();
        let depth = raycast_depth(&vertices, &triangles, &view).unwrap();
        // Sagitta of a triangle of diameter h·√2 on a sphere of radius r (slopes here are < 0.3).
        let bound = 1.2 * (h * 2f32.sqrt()).powi(2) / (8.0 * r);
        let mut worst = 0.0f32;
        for i in 0..32 {
            for j in 0..32 {
                let (x, y) = view.world(i as f32 + 0.5, j as f32 + 0.5);
                let exact = CAMERA_Z - ((r * r - x * x - y * y).sqrt() - r);
                worst = worst.max((depth[i * 32 + j] - exact).abs());
                // Chords lie inside the sphere: the mesh is never above it.
                assert!(depth[i * 32 + j] >= exact - 1e-5);
            }
        }
        assert!(worst <= bound, "worst {worst} > bound {bound}");
        assert!(worst > 0.0);
    }

    #[test]
    fn misses_are_nan_and_hits_above_the_camera_are_ignored() {
        let vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 5.0], [1.0, 0.0, 5.0], [0.0, 1.0, 5.0]];
        let triangles = [[0, 1, 2], [3, 4, 5]];
        let view = View::new(2, 2, [0.0, 0.0, 1.0, 1.0], CAMERA_Z).unwrap();
        let depth = raycast_depth(&vertices, &triangles, &view).unwrap();
        // Row 0 is the top (y = 0.75): pixel (0, 0) at (0.25, 0.75) hits, (0, 1) at (0.75, 0.75) misses.
        assert_eq!(depth[0], CAMERA_Z);
        assert!(depth[1].is_nan());
    }
}
