//! Reads mesh colliders (`--collider mesh:FILE[#NAME]`): the triangles of an OBJ, glTF or GLB
//! file, or of one named object in it.

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::{gltf_mesh, obj};
use crate::mesh::Mesh;

/// Reads the collider mesh in `path`: every face of an OBJ, or only its `o`/`g` object `part`;
/// every mesh node of a glTF/GLB's scene in world space, or only the node or mesh named `part`.
/// Positions are the file's, unplaced.
///
/// # Errors
/// [`Error::Value`] naming the file and the names it holds when `part` names nothing in it, or
/// when the file is not an OBJ, glTF or GLB (the job names `--collider`); the readers' errors
/// (naming the file, and the line for an OBJ).
pub fn load_collider_mesh(path: &Path, part: Option<&str>) -> Result<Mesh> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("obj") => obj::load_obj(
            path,
            &obj::ObjOptions {
                object: part.map(str::to_owned),
            },
        ),
        Some("gltf" | "glb") => gltf_mesh::load_gltf_collider(path, part),
        _ => Err(Error::value(format!(
            "mesh:{}: a mesh collider is an .obj, .gltf or .glb file",
            path.display()
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    /// Two objects: a unit triangle at y = 0 and a quad at y = 5; `#NAME` keeps one.
    #[test]
    fn an_obj_part_keeps_only_that_object() {
        let dir = tempfile::tempdir().unwrap();
        let p = write(
            dir.path(),
            "two.obj",
            "o floor\nv 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\no shelf\nv 0 5 0\nv 1 5 0\nv 1 5 1\nv 0 5 1\nf 4 5 6 7\n",
        );
        let all = load_collider_mesh(&p, None).unwrap();
        assert_eq!((all.positions.len(), all.triangles.len()), (7, 3));
        let shelf = load_collider_mesh(&p, Some("shelf")).unwrap();
        assert_eq!(shelf.triangles.len(), 2);
        assert!(shelf.positions.iter().all(|q| q.y == 5.0));
        let floor = load_collider_mesh(&p, Some("floor")).unwrap();
        assert_eq!(floor.triangles.len(), 1);
        assert!(floor.positions.iter().all(|q| q.y == 0.0));
        let e = load_collider_mesh(&p, Some("roof")).unwrap_err();
        assert!(matches!(e, Error::Value { .. }), "{e}");
        assert!(
            e.to_string().contains("no object or group named `roof`"),
            "{e}"
        );
        assert!(e.to_string().contains("(known: floor, shelf)"), "{e}");
    }

    #[test]
    fn other_formats_are_refused_as_values() {
        let e = load_collider_mesh(Path::new("body.tet"), None).unwrap_err();
        assert!(matches!(e, Error::Value { .. }), "{e}");
        assert!(
            e.to_string().contains("mesh:body.tet: a mesh collider is"),
            "{e}"
        );
    }
}
