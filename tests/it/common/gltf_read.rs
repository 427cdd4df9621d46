//! A glTF reloaded for the tests: the `gltf` crate parses and validates the JSON; the buffers are
//! read here by the glTF 2.0 specification (the GLB's BIN chunk, files beside the glTF with
//! percent-encoded relative URIs, base64 data URIs), independent of `src/io/gltf_import.rs`.
//! The crate's own `import` feature would do the same and build an image decoder the tests do
//! not use (and a second copy of every crate whose features it changes).

use std::path::Path;

use base64::Engine;

/// One buffer's bytes (dereferences to `[u8]`, as the `gltf` crate's readers take them).
#[derive(Debug, Clone)]
pub struct Data(pub Vec<u8>);

impl std::ops::Deref for Data {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        &self.0
    }
}

/// The document and its buffers (and no images: the third value stands where the `gltf`
/// crate's `import` returns them).
pub fn import(path: impl AsRef<Path>) -> Result<(gltf::Document, Vec<Data>, ()), String> {
    let path = path.as_ref();
    let gltf = gltf::Gltf::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let buffers = import_buffers(&gltf.document, path.parent(), gltf.blob.clone())?;
    Ok((gltf.document, buffers, ()))
}

/// The buffers of `doc`: the GLB `blob` for a buffer without a URI, files relative to `base`,
/// data URIs; each checked to hold at least its declared byteLength.
pub fn import_buffers(
    doc: &gltf::Document,
    base: Option<&Path>,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<Data>, String> {
    doc.buffers()
        .map(|b| {
            let bytes = match b.source() {
                gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                    format!("buffer {} has no URI and there is no BIN chunk", b.index())
                })?,
                gltf::buffer::Source::Uri(uri) => read_uri(base, uri)?,
            };
            if bytes.len() < b.length() {
                return Err(format!(
                    "buffer {} holds {} bytes, fewer than its byteLength {}",
                    b.index(),
                    bytes.len(),
                    b.length()
                ));
            }
            Ok(Data(bytes))
        })
        .collect()
}

fn read_uri(base: Option<&Path>, uri: &str) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, data) = rest
            .split_once(";base64,")
            .ok_or_else(|| format!("data URI without base64: {uri:.40}"))?;
        return base64::engine::general_purpose::STANDARD
            .decode(data)
            .map_err(|e| format!("data URI: {e}"));
    }
    let base = base.ok_or("a relative URI needs the glTF's folder")?;
    let path = base.join(percent_decode(uri)?);
    std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))
}

/// Decodes %XX escapes of a URI (RFC 3986).
fn percent_decode(uri: &str) -> Result<String, String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = uri
                .get(i + 1..i + 3)
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("bad escape in URI {uri}"))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| format!("URI {uri} is not UTF-8 once decoded"))
}
