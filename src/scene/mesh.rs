//! Triangle meshes from OBJ (via `tobj`, which triangulates polygons) and PLY (via `ply-rs-bw`,
//! ASCII and binary). Both crates are maintained and read the files CAD and photogrammetry tools
//! export; hand-written parsers would add formats' corner cases for no gain.

use super::SceneError;
use nalgebra::Vector3;
use ply_rs_bw::ply::Property;
use std::path::Path;

/// Triangles of a mesh file, in the file's units.
pub fn load(path: &Path) -> Result<Vec<[Vector3<f64>; 3]>, SceneError> {
    let err = |message: String| SceneError::Mesh {
        path: path.to_owned(),
        message,
    };
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let tris = match ext.as_deref() {
        Some("obj") => {
            let opts = tobj::LoadOptions {
                triangulate: true,
                single_index: false,
                ..Default::default()
            };
            let (models, _) = tobj::load_obj(path, &opts).map_err(|e| err(e.to_string()))?;
            let mut tris = Vec::new();
            for m in models {
                let pos = &m.mesh.positions;
                let v = |i: u32| -> Result<Vector3<f64>, SceneError> {
                    let i = i as usize * 3;
                    pos.get(i..i + 3)
                        .map(|p| Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
                        .ok_or_else(|| err(format!("vertex index {} out of range", i / 3)))
                };
                for f in m.mesh.indices.chunks_exact(3) {
                    tris.push([v(f[0])?, v(f[1])?, v(f[2])?]);
                }
            }
            tris
        }
        Some("ply") => {
            let mut file = std::fs::File::open(path).map_err(|e| err(e.to_string()))?;
            let parser = ply_rs_bw::parser::Parser::<ply_rs_bw::ply::DefaultElement>::new();
            let ply = parser
                .read_ply(&mut std::io::BufReader::new(&mut file))
                .map_err(|e| err(e.to_string()))?;
            let num = |p: Option<&Property>| -> Option<f64> {
                Some(match p? {
                    Property::Float(v) => f64::from(*v),
                    Property::Double(v) => *v,
                    Property::Int(v) => f64::from(*v),
                    Property::UInt(v) => f64::from(*v),
                    Property::Short(v) => f64::from(*v),
                    Property::UShort(v) => f64::from(*v),
                    Property::Char(v) => f64::from(*v),
                    Property::UChar(v) => f64::from(*v),
                    _ => return None,
                })
            };
            let verts: Vec<Vector3<f64>> = ply
                .payload
                .get("vertex")
                .ok_or_else(|| err("no 'vertex' element".into()))?
                .iter()
                .enumerate()
                .map(
                    |(i, e)| match (num(e.get("x")), num(e.get("y")), num(e.get("z"))) {
                        (Some(x), Some(y), Some(z)) => Ok(Vector3::new(x, y, z)),
                        _ => Err(err(format!("vertex {i} lacks a numeric x, y or z"))),
                    },
                )
                .collect::<Result<_, _>>()?;
            let mut tris = Vec::new();
            for (i, f) in ply.payload.get("face").into_iter().flatten().enumerate() {
                let idx: Vec<i64> = match f.get("vertex_indices").or_else(|| f.get("vertex_index"))
                {
                    Some(Property::ListInt(v)) => v.iter().map(|&x| i64::from(x)).collect(),
                    Some(Property::ListUInt(v)) => v.iter().map(|&x| i64::from(x)).collect(),
                    Some(Property::ListUChar(v)) => v.iter().map(|&x| i64::from(x)).collect(),
                    Some(Property::ListUShort(v)) => v.iter().map(|&x| i64::from(x)).collect(),
                    Some(Property::ListShort(v)) => v.iter().map(|&x| i64::from(x)).collect(),
                    _ => return Err(err(format!("face {i} has no integer vertex_indices"))),
                };
                let get = |k: i64| {
                    usize::try_from(k)
                        .ok()
                        .and_then(|k| verts.get(k).copied())
                        .ok_or_else(|| err(format!("face {i}: vertex index {k} out of range")))
                };
                // Fan-triangulate convex polygons.
                for k in 1..idx.len().saturating_sub(1) {
                    tris.push([get(idx[0])?, get(idx[k])?, get(idx[k + 1])?]);
                }
            }
            tris
        }
        _ => {
            return Err(err(
                "unknown mesh format: expected a .obj or .ply file".into()
            ))
        }
    };
    if tris.is_empty() {
        return Err(err("no triangles".into()));
    }
    Ok(tris)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn obj_and_ply_give_the_same_quad() {
        let dir = tempfile::tempdir().unwrap();
        let obj = dir.path().join("q.obj");
        std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
        let ply = dir.path().join("q.ply");
        std::fs::write(
            &ply,
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
             property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
             0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n",
        )
        .unwrap();
        let a = load(&obj).unwrap();
        let b = load(&ply).unwrap();
        assert_eq!(a.len(), 2);
        assert_eq!(b.len(), 2);
        let area = |t: &[[Vector3<f64>; 3]]| -> f64 {
            t.iter()
                .map(|[p, q, r]| (q - p).cross(&(r - p)).norm() / 2.0)
                .sum()
        };
        assert!((area(&a) - 1.0).abs() < 1e-12 && (area(&b) - 1.0).abs() < 1e-12);
        std::fs::write(
            &ply,
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
             property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
             0 0 0\n3 0 1 2\n",
        )
        .unwrap();
        let e = load(&ply).unwrap_err().to_string();
        assert!(e.contains("out of range"), "{e}");
    }
}
