//! The CSV files of `probe` and `bench`: points in (x,y,z,nx,ny,nz), values out
//! (x,y,z,r,g,b), reference tables.

use anyhow::{Context, Result};
use glam::{DVec3, Vec3};
use std::path::Path;

/// Reads a points CSV: header naming x,y,z,nx,ny,nz (any order, extra columns ignored).
/// Returns world-space points and normals.
pub fn read_points(path: &Path) -> Result<Vec<(DVec3, DVec3)>> {
    Ok(read_table(path, &["x", "y", "z", "nx", "ny", "nz"])?
        .into_iter()
        .map(|r| (DVec3::new(r[0], r[1], r[2]), DVec3::new(r[3], r[4], r[5])))
        .collect())
}

/// Reads the named numeric columns of a CSV with a header row.
pub fn read_table(path: &Path, columns: &[&str]) -> Result<Vec<Vec<f64>>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header: Vec<&str> = lines
        .next()
        .with_context(|| {
            format!(
                "{}: empty file (expected a header {})",
                path.display(),
                columns.join(",")
            )
        })?
        .split(',')
        .map(str::trim)
        .collect();
    let index: Vec<usize> = columns
        .iter()
        .map(|c| {
            header.iter().position(|h| h == c).with_context(|| {
                format!(
                    "{}: header has no column '{c}' (expected {})",
                    path.display(),
                    columns.join(",")
                )
            })
        })
        .collect::<Result<_>>()?;
    let mut rows = Vec::new();
    for (k, line) in lines.enumerate() {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let row = index
            .iter()
            .map(|&i| {
                let cell = cells.get(i).copied().unwrap_or("");
                cell.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .with_context(|| {
                        format!(
                            "{}: line {}: '{cell}' is not a finite number",
                            path.display(),
                            k + 2
                        )
                    })
            })
            .collect::<Result<Vec<f64>>>()?;
        rows.push(row);
    }
    Ok(rows)
}

/// The `values.csv` text: header `x,y,z,r,g,b`, one row per point, in order.
pub fn values_csv(points: &[(DVec3, DVec3)], values: &[Vec3]) -> String {
    let mut csv = String::from("x,y,z,r,g,b\n");
    for ((p, _), v) in points.iter().zip(values) {
        csv += &format!("{},{},{},{},{},{}\n", p.x, p.y, p.z, v.x, v.y, v.z);
    }
    csv
}
