//! Collision geometry from URDF elements that are not a single capsule: mesh files (STL binary
//! or ASCII, Wavefront OBJ), boxes, and several elements on one body. Each becomes a set of
//! points with a radius, and one capsule is fitted around all of them (it encloses every point
//! inflated by its radius), so the checker keeps one capsule per moving body.
//!
//! Mesh paths: `package://NAME/rest` is looked up in each directory of the search path (a
//! directory holding package folders, or the package folder itself), then in the
//! `ROS_PACKAGE_PATH` directories, then in the URDF's folder and each folder above it (a
//! package `NAME` that holds the URDF, as `NAME/urdf/arm.urdf`, or a folder holding it beside
//! the URDF's own package); `file:///abs` and absolute paths are used as they are; a relative
//! path is taken from the URDF's folder.

use std::io::{BufReader, Cursor};
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};

/// Mesh files larger than this are refused (a wrong path cannot make the loader read a
/// device or a huge file), bytes.
pub const MESH_LIMIT: u64 = 128 << 20;

/// Where `filename` (as written in a URDF `<mesh filename=...>`) is on disk.
pub fn resolve(filename: &str, urdf_dir: Option<&Path>, package_path: &[PathBuf]) -> Result<PathBuf, String> {
    if let Some(rest) = filename.strip_prefix("package://") {
        let (pkg, rel) =
            rest.split_once('/').ok_or_else(|| format!("`{filename}`: no path after the package name"))?;
        let ros: Vec<PathBuf> = std::env::var_os("ROS_PACKAGE_PATH")
            .map(|v| std::env::split_paths(&v).collect())
            .unwrap_or_default();
        let mut tried = Vec::new();
        // Last, the URDF's own folders: a package that holds the URDF, or holds it beside it
        // (a workspace of packages), as a package folder is laid out.
        let own: Vec<PathBuf> = urdf_dir
            .map(|d| std::path::absolute(d).unwrap_or_else(|_| d.to_path_buf()))
            .map(|d| d.ancestors().map(Path::to_path_buf).collect())
            .unwrap_or_default();
        for dir in package_path.iter().chain(ros.iter()).chain(own.iter()) {
            // A directory holding package folders, or the package folder itself.
            let mut candidates = vec![dir.join(pkg).join(rel)];
            if dir.file_name().is_some_and(|n| n == pkg) {
                candidates.push(dir.join(rel));
            }
            for c in candidates {
                if c.is_file() {
                    return Ok(c);
                }
                tried.push(c.display().to_string());
            }
        }
        return Err(if package_path.is_empty() && ros.is_empty() {
            format!(
                "`{filename}`: package `{pkg}` not found in the URDF's folders (no search path: set \
                 robot.package_path or ROS_PACKAGE_PATH)"
            )
        } else {
            format!("`{filename}`: package `{pkg}` not found; tried {}", tried.join(", "))
        });
    }
    let p = filename.strip_prefix("file://").unwrap_or(filename);
    let p = Path::new(p);
    let full = match (p.is_absolute(), urdf_dir) {
        (true, _) => p.to_path_buf(),
        (false, Some(d)) => d.join(p),
        (false, None) => p.to_path_buf(),
    };
    if full.is_file() {
        Ok(full)
    } else {
        Err(format!("`{filename}`: no such file {}", full.display()))
    }
}

/// The vertices of a mesh file (`.stl`, binary or ASCII; `.obj`), scaled by `scale`.
pub fn load_vertices(path: &Path, scale: [f64; 3]) -> Result<Vec<Point3<f64>>, String> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if !matches!(ext.as_str(), "stl" | "obj") {
        return Err(format!(
            "{}: unsupported mesh format `.{ext}` (STL or OBJ; convert COLLADA/other meshes to one of them)",
            path.display()
        ));
    }
    let bytes = dkrrt_io::read_capped(path, MESH_LIMIT).map_err(|e| format!("{}: {e}", path.display()))?;
    let raw: Vec<[f64; 3]> = match ext.as_str() {
        "stl" => {
            let mesh = stl_io::read_stl(&mut Cursor::new(&bytes))
                .map_err(|e| format!("{}: not a readable STL file: {e}", path.display()))?;
            mesh.vertices.iter().map(|v| [v[0] as f64, v[1] as f64, v[2] as f64]).collect()
        }
        _ => {
            let opts = tobj::LoadOptions::default();
            let (models, _materials) =
                tobj::load_obj_buf(&mut BufReader::new(Cursor::new(&bytes)), &opts, |_| {
                    Err(tobj::LoadError::OpenFileFailed)
                })
                .map_err(|e| format!("{}: not a readable OBJ file: {e}", path.display()))?;
            models
                .iter()
                .flat_map(|m| {
                    m.mesh.positions.chunks_exact(3).map(|c| [c[0] as f64, c[1] as f64, c[2] as f64])
                })
                .collect()
        }
    };
    if raw.is_empty() {
        return Err(format!("{}: the mesh has no vertices", path.display()));
    }
    let pts: Vec<Point3<f64>> =
        raw.iter().map(|v| Point3::new(v[0] * scale[0], v[1] * scale[1], v[2] * scale[2])).collect();
    if pts.iter().any(|p| !p.coords.iter().all(|x| x.is_finite())) {
        return Err(format!("{}: non-finite vertex", path.display()));
    }
    Ok(pts)
}

/// A capsule (segment `a`–`b`, `radius`) enclosing every point inflated by its radius: every
/// `(p, r)` has `dist(p, segment) + r <= radius`. The axis is the points' principal axis.
pub fn fit_capsule(points: &[(Point3<f64>, f64)]) -> (Point3<f64>, Point3<f64>, f64) {
    let n = points.len().max(1) as f64;
    let c = points.iter().fold(Vector3::zeros(), |s, (p, _)| s + p.coords) / n;
    let mut cov = Matrix3::zeros();
    for (p, _) in points {
        let d = p.coords - c;
        cov += d * d.transpose();
    }
    let eig = SymmetricEigen::new(cov);
    let (imax, lmax) =
        eig.eigenvalues.iter().enumerate().fold((0, f64::MIN), |m, (i, &l)| if l > m.1 { (i, l) } else { m });
    let u: Vector3<f64> = if lmax > 1e-18 { eig.eigenvectors.column(imax).normalize() } else { Vector3::z() };
    let axial = |p: &Point3<f64>| (p.coords - c).dot(&u);
    let radial = |p: &Point3<f64>| ((p.coords - c) - u * axial(p)).norm();
    let radius = points.iter().map(|(p, r)| radial(p) + r).fold(0.0, f64::max);
    // Shortest segment [lo, hi] along the axis that keeps every inflated point inside.
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (p, r) in points {
        let (t, d) = (axial(p), radial(p));
        let room = ((radius - r).powi(2) - d * d).max(0.0).sqrt();
        lo = lo.min(t + room);
        hi = hi.max(t - room);
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return (Point3::from(c), Point3::from(c), radius);
    }
    if lo > hi {
        let m = 0.5 * (lo + hi);
        (lo, hi) = (m, m);
    }
    (Point3::from(c + u * lo), Point3::from(c + u * hi), radius)
}
