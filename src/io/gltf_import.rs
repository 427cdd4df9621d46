//! The one door through which every glTF input is loaded.
//!
//! It checks, before the `gltf` crate's own validation runs, for what that validation cannot
//! report itself: missing external files (it says only "not found"), a POSITION attribute naming
//! an accessor that does not exist (its validator indexes the accessor list unchecked and panics),
//! and an image without the `mimeType` or `uri` its source needs (validation lets it through and
//! the image loader unwraps it). Both panics were found by fuzzing; their inputs are kept in
//! `tests/fixtures/`.

use std::path::Path;

use crate::error::{Error, Result};

/// A loaded document with the bytes of each of its buffers (`buffers[i]` is `buffers[i]` of the
/// document, at least `byteLength` long). Images are not decoded: nothing here reads pixels.
pub type Imported = (gltf::Document, Vec<Vec<u8>>);

/// Loads a `.gltf` or `.glb` with its buffers (the GLB binary chunk, `data:` URIs, files beside
/// it).
///
/// # Errors
/// [`Error::Io`] for an unreadable file, [`Error::InvalidInput`] naming the element for the
/// hazards above and for short or undecodable buffers, [`Error::Gltf`] for everything the `gltf`
/// crate rejects.
pub fn import_gltf(path: &Path) -> Result<Imported> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if let Ok(unchecked) = gltf::Gltf::from_slice_without_validation(&bytes) {
        check_position_accessors(path, &unchecked)?;
        check_image_sources(path, &unchecked)?;
        check_external_files(path, &unchecked)?;
    }
    let gltf = gltf::Gltf::from_slice(&bytes).map_err(|error| Error::Gltf {
        path: path.into(),
        source: error,
    })?;
    let buffers = load_buffers(path, &gltf)?;
    Ok((gltf.document, buffers))
}

/// As [`import_gltf`], but also accepts files that require KHR_mesh_quantization (which the
/// `gltf` crate's validation refuses as unsupported), for callers that read only the document
/// structure and float data (`inspect`); every other validation error is still reported.
///
/// # Errors
/// As [`import_gltf`].
pub fn import_gltf_for_inspection(path: &Path) -> Result<Imported> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let Ok(unchecked) = gltf::Gltf::from_slice_without_validation(&bytes) else {
        return import_gltf(path);
    };
    let root = unchecked.document.as_json();
    if !root
        .extensions_required
        .iter()
        .any(|e| e == crate::data::KHR_MESH_QUANTIZATION)
    {
        return import_gltf(path);
    }
    check_position_accessors(path, &unchecked)?;
    check_image_sources(path, &unchecked)?;
    check_external_files(path, &unchecked)?;
    let mut errors = Vec::new();
    gltf::json::validation::Validate::validate(
        root,
        root,
        gltf::json::Path::new,
        &mut |p: &dyn Fn() -> gltf::json::Path, e| {
            let p = p();
            let quantization = matches!(e, gltf::json::validation::Error::Unsupported)
                && p.as_str().contains(crate::data::KHR_MESH_QUANTIZATION);
            if !quantization {
                errors.push((p, e));
            }
        },
    );
    if !errors.is_empty() {
        return Err(Error::Gltf {
            path: path.into(),
            source: gltf::Error::Validation(errors),
        });
    }
    let buffers = load_buffers(path, &unchecked)?;
    Ok((unchecked.document, buffers))
}

/// The bytes of every buffer of `gltf` (loaded from `path`): the GLB binary chunk, a base64
/// `data:` URI, or a file beside the glTF.
fn load_buffers(path: &Path, gltf: &gltf::Gltf) -> Result<Vec<Vec<u8>>> {
    use base64::Engine as _;
    let mut out = Vec::new();
    for buffer in gltf.document.buffers() {
        let i = buffer.index();
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                Error::invalid(
                    path,
                    format!("buffer {i} refers to the GLB binary chunk, but the file has none"),
                )
            })?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                let (_, payload) = uri.split_once(";base64,").ok_or_else(|| {
                    Error::invalid(path, format!("buffer {i}: a data URI that is not base64"))
                })?;
                base64::engine::general_purpose::STANDARD
                    .decode(payload)
                    .map_err(|e| {
                        Error::invalid(path, format!("buffer {i}: invalid base64 data ({e})"))
                    })?
            }
            gltf::buffer::Source::Uri(uri) => {
                let file = uri_path(path, uri);
                std::fs::read(&file).map_err(|e| Error::io(&file, e))?
            }
        };
        if data.len() < buffer.length() {
            return Err(Error::invalid(
                path,
                format!(
                    "buffer {i} has {} bytes, but its byteLength is {}",
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

fn check_position_accessors(path: &Path, gltf: &gltf::Gltf) -> Result<()> {
    let root = gltf.document.as_json();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &prim.attributes {
                if index.value() >= root.accessors.len() {
                    let name = match semantic {
                        gltf::json::validation::Checked::Valid(s) => s.to_string(),
                        gltf::json::validation::Checked::Invalid => "?".into(),
                    };
                    return Err(Error::invalid(
                        path,
                        format!("meshes[{m}].primitives[{p}].attributes.{name} refers to accessor {}, but the file has {} accessors", index.value(), root.accessors.len()),
                    ));
                }
            }
        }
    }
    Ok(())
}

fn check_image_sources(path: &Path, gltf: &gltf::Gltf) -> Result<()> {
    for (i, image) in gltf.document.as_json().images.iter().enumerate() {
        let problem = match (&image.buffer_view, &image.mime_type, &image.uri) {
            (Some(_), None, _) => "has a bufferView but no mimeType (glTF 2.0 requires one)",
            (None, _, None) => "has neither a uri nor a bufferView",
            _ => continue,
        };
        return Err(Error::invalid(path, format!("images[{i}] {problem}")));
    }
    Ok(())
}

fn check_external_files(path: &Path, gltf: &gltf::Gltf) -> Result<()> {
    // Raw JSON fields only: the document is not validated yet, and the crate's accessors
    // (`Image::source` and friends) unwrap fields that validation would have checked.
    let root = gltf.document.as_json();
    let buffers = root
        .buffers
        .iter()
        .enumerate()
        .filter_map(|(i, b)| b.uri.as_deref().map(|u| ("buffer", i, u)));
    let images = root
        .images
        .iter()
        .enumerate()
        .filter_map(|(i, im)| im.uri.as_deref().map(|u| ("image", i, u)));
    let uris = buffers.chain(images);
    for (what, index, uri) in uris {
        let file = uri_path(path, uri);
        if !uri.starts_with("data:") && !file.exists() {
            return Err(Error::invalid(
                path,
                format!("{what} {index} refers to `{uri}`, which does not exist (expected beside the .gltf, at {})", file.display()),
            ));
        }
    }
    Ok(())
}

/// The file a relative URI of the glTF at `gltf_path` points to (percent-escapes decoded).
pub fn uri_path(gltf_path: &Path, uri: &str) -> std::path::PathBuf {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let escaped = (bytes[i] == b'%' && i + 2 < bytes.len())
            .then(|| {
                std::str::from_utf8(&bytes[i + 1..i + 3])
                    .ok()
                    .and_then(|h| u8::from_str_radix(h, 16).ok())
            })
            .flatten();
        match escaped {
            Some(v) => {
                out.push(v);
                i += 3;
            }
            None => {
                out.push(bytes[i]);
                i += 1;
            }
        }
    }
    gltf_path
        .parent()
        .unwrap_or(Path::new(""))
        .join(String::from_utf8_lossy(&out).as_ref())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uris_are_decoded_without_panicking_on_odd_escapes() {
        let p = Path::new("dir/scene.gltf");
        assert_eq!(uri_path(p, "my%20mesh.bin"), Path::new("dir/my mesh.bin"));
        assert_eq!(uri_path(p, "%é%zz%4"), Path::new("dir/%é%zz%4"));
    }
}
