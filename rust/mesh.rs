//! Topology of the regular surface grid.
//!
//! Vertex (row `jy`, column `jx`) of a `grid × grid` mesh has index
//! `jy · grid + jx`. Each cell is split along its (jy, jx)–(jy+1, jx+1)
//! diagonal into two triangles wound counter-clockwise seen from +z (the
//! camera side) in the undeformed patch, so their normals point at the camera.

use crate::error::{size_in, Result};
use crate::synthesis::MAX_GRID;

/// Triangle indices, shape (2 (grid − 1)², 3) flattened.
pub fn grid_triangles(grid: i64) -> Result<Vec<u32>> {
    let g = size_in("grid", grid, 2, MAX_GRID)?;
    let mut tris = Vec::with_capacity(6 * (g - 1) * (g - 1));
    for jy in 0..g - 1 {
        for jx in 0..g - 1 {
            let v00 = (jy * g + jx) as u32;
            let (v01, v10, v11) = (v00 + 1, v00 + g as u32, v00 + g as u32 + 1);
            tris.extend_from_slice(&[v00, v01, v11, v00, v11, v10]);
        }
    }
    Ok(tris)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthesis::grid_coordinate;

    #[test]
    fn triangles_tile_the_square_once_and_face_the_camera() {
        for g in [2usize, 3, 10] {
            let tris = grid_triangles(g as i64).unwrap();
            assert_eq!(tris.len(), 6 * (g - 1) * (g - 1));
            let pos = |v: u32| (grid_coordinate(v as usize % g, g), grid_coordinate(v as usize / g, g));
            let mut area = 0.0;
            for t in tris.chunks(3) {
                let (a, b, c) = (pos(t[0]), pos(t[1]), pos(t[2]));
                let cross = (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
                assert!(cross > 0.0, "triangle {t:?} is not counter-clockwise");
                area += cross / 2.0;
            }
            assert!((area - 4.0).abs() < 1e-12);
        }
        assert_eq!(grid_triangles(1).unwrap_err().name, "grid");
    }
}
