//! `scenebake view FILE`: the browser viewer (`viewer/`, embedded in the binary) and the bake,
//! served over HTTP on 127.0.0.1 until Ctrl-C.
//!
//! Routes: `/` is the viewer's page, `/NAME` its modules and the vendored three.js, and
//! `/file/NAME` any file in FILE's folder (the bake, a glTF's `.bin`, a VAT's images and JSON;
//! plain names only, nothing above or below that folder).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::Args;

/// The viewer's files, as `viewer/` holds them (a test checks the list against the folder).
const ASSETS: &[(&str, &[u8])] = &[
    ("index.html", include_bytes!("../../viewer/index.html")),
    ("main.js", include_bytes!("../../viewer/main.js")),
    ("bake.js", include_bytes!("../../viewer/bake.js")),
    ("vat.js", include_bytes!("../../viewer/vat.js")),
    (
        "vendor/three/build/three.module.js",
        include_bytes!("../../viewer/vendor/three/build/three.module.js"),
    ),
    (
        "vendor/three/build/three.core.js",
        include_bytes!("../../viewer/vendor/three/build/three.core.js"),
    ),
    (
        "vendor/three/examples/jsm/controls/OrbitControls.js",
        include_bytes!("../../viewer/vendor/three/examples/jsm/controls/OrbitControls.js"),
    ),
    (
        "vendor/three/examples/jsm/libs/fflate.module.js",
        include_bytes!("../../viewer/vendor/three/examples/jsm/libs/fflate.module.js"),
    ),
    (
        "vendor/three/examples/jsm/libs/meshopt_decoder.module.js",
        include_bytes!("../../viewer/vendor/three/examples/jsm/libs/meshopt_decoder.module.js"),
    ),
    (
        "vendor/three/examples/jsm/loaders/EXRLoader.js",
        include_bytes!("../../viewer/vendor/three/examples/jsm/loaders/EXRLoader.js"),
    ),
    (
        "vendor/three/examples/jsm/loaders/GLTFLoader.js",
        include_bytes!("../../viewer/vendor/three/examples/jsm/loaders/GLTFLoader.js"),
    ),
    (
        "vendor/three/examples/jsm/utils/BufferGeometryUtils.js",
        include_bytes!("../../viewer/vendor/three/examples/jsm/utils/BufferGeometryUtils.js"),
    ),
    (
        "vendor/three/examples/jsm/utils/SkeletonUtils.js",
        include_bytes!("../../viewer/vendor/three/examples/jsm/utils/SkeletonUtils.js"),
    ),
    (
        "vendor/three/LICENSE",
        include_bytes!("../../viewer/vendor/three/LICENSE"),
    ),
];

/// Play a bake in the browser: a local web server for the built-in three.js viewer.
#[derive(Debug, Args)]
#[command(after_help = "Examples:\n  scenebake view exports/lab_cloth.glb\n  \
        scenebake view exports/lab_cloth.json          (the VAT: its EXR images on the glTF's mesh)\n  \
        scenebake view exports/flag.glb --frame 90 --no-open --port 8000\n\n\
        Serves FILE's folder and the viewer on 127.0.0.1 until Ctrl-C; prints the URL.")]
pub struct ViewArgs {
    /// The bake: a .glb/.gltf, or a vertex-animation texture's .json (or its .exr).
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    /// The port to listen on (0: any free port).
    #[arg(long, default_value_t = 0)]
    pub port: u16,
    /// Show this frame only, paused (the URL gets `&frame=N`).
    #[arg(long, value_name = "N")]
    pub frame: Option<usize>,
    /// Print the URL without opening a browser.
    #[arg(long)]
    pub no_open: bool,
}

/// The MIME type the browser needs for `name` (module scripts must be JavaScript).
fn content_type(name: &str) -> &'static str {
    let ext = name.rsplit('.').next().unwrap_or("").to_ascii_lowercase();
    match ext.as_str() {
        "html" => "text/html; charset=utf-8",
        "js" | "mjs" => "text/javascript; charset=utf-8",
        "json" => "application/json",
        "gltf" => "model/gltf+json",
        "glb" => "model/gltf-binary",
        "exr" => "image/x-exr",
        "png" => "image/png",
        "jpg" | "jpeg" => "image/jpeg",
        _ => "application/octet-stream",
    }
}

/// `%XX` escapes decoded; `None` for invalid escapes or UTF-8.
fn percent_decode(text: &str) -> Option<String> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// What a request path is answered with.
#[derive(Debug, PartialEq)]
enum Route {
    /// An embedded viewer file.
    Asset(&'static str, &'static [u8]),
    /// A file of the bake's folder.
    File(PathBuf),
    /// Nothing here.
    NotFound,
}

/// Maps a request URL (path and query) to what is served; files only from `dir`.
fn route(url: &str, dir: &Path) -> Route {
    let path = url.split(['?', '#']).next().unwrap_or("");
    let Some(path) = percent_decode(path) else {
        return Route::NotFound;
    };
    let path = path.trim_start_matches('/');
    let path = if path.is_empty() { "index.html" } else { path };
    if let Some(name) = path.strip_prefix("file/") {
        let plain =
            !name.is_empty() && !name.contains(['/', '\\', '\0']) && name != "." && name != "..";
        return if plain {
            Route::File(dir.join(name))
        } else {
            Route::NotFound
        };
    }
    ASSETS
        .iter()
        .find(|(n, _)| *n == path)
        .map_or(Route::NotFound, |(n, bytes)| Route::Asset(n, bytes))
}

/// The page URL for the bake: `http://127.0.0.1:PORT/?file=file/NAME[&frame=N]`.
fn page_url(port: u16, name: &str, frame: Option<usize>) -> String {
    let mut escaped = String::new();
    for b in name.bytes() {
        if b.is_ascii_alphanumeric() || b"-_.~".contains(&b) {
            escaped.push(b as char);
        } else {
            escaped += &format!("%{b:02X}");
        }
    }
    let mut url = format!("http://127.0.0.1:{port}/?file=file/{escaped}");
    if let Some(f) = frame {
        url += &format!("&frame={f}");
    }
    url
}

/// Asks the desktop to open `url` in the default browser; false when that failed.
fn open_browser(url: &str) -> bool {
    let mut command = if cfg!(target_os = "macos") {
        std::process::Command::new("open")
    } else if cfg!(windows) {
        let mut c = std::process::Command::new("cmd");
        c.args(["/C", "start", ""]);
        c
    } else {
        std::process::Command::new("xdg-open")
    };
    command
        .arg(url)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .is_ok()
}

/// Serves until the process is stopped.
pub fn run(args: &ViewArgs) -> anyhow::Result<()> {
    let file = &args.file;
    let ext = file
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("glb" | "gltf" | "json" | "exr")) {
        bail!(
            "{}: expected a .glb or .gltf bake, or a vertex-animation texture's .json or .exr",
            file.display()
        );
    }
    if !file.is_file() {
        bail!("{}: no such file", file.display());
    }
    let absolute = std::path::absolute(file).unwrap_or_else(|_| file.clone());
    let dir = absolute.parent().map(Path::to_path_buf).unwrap_or_default();
    let name = absolute
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let server = tiny_http::Server::http(("127.0.0.1", args.port))
        .map_err(|e| anyhow::anyhow!("cannot listen on 127.0.0.1:{}: {e}", args.port))?;
    let port = server
        .server_addr()
        .to_ip()
        .map(|a| a.port())
        .context("the server has no TCP address")?;
    let url = page_url(port, &name, args.frame);
    println!("{url}");
    std::io::stdout().flush().ok();
    eprintln!(
        "serving {} and the viewer at http://127.0.0.1:{port}/ (Ctrl-C stops)",
        file.display()
    );
    if !args.no_open && !open_browser(&url) {
        eprintln!("could not start a browser: open the URL above yourself");
    }
    for request in server.incoming_requests() {
        let response = match route(request.url(), &dir) {
            Route::Asset(n, bytes) => respond(bytes.to_vec(), content_type(n), 200),
            Route::File(path) => match std::fs::read(&path) {
                Ok(bytes) => respond(bytes, content_type(&path.to_string_lossy()), 200),
                Err(e) => respond(
                    format!("{}: {e}", path.display()).into_bytes(),
                    "text/plain; charset=utf-8",
                    404,
                ),
            },
            Route::NotFound => respond(b"not found".to_vec(), "text/plain; charset=utf-8", 404),
        };
        // A browser that went away mid-response is no reason to stop serving.
        let _ = request.respond(response);
    }
    Ok(())
}

fn respond(
    bytes: Vec<u8>,
    mime: &str,
    status: u16,
) -> tiny_http::Response<std::io::Cursor<Vec<u8>>> {
    let mut response = tiny_http::Response::from_data(bytes).with_status_code(status);
    for (field, value) in [("Content-Type", mime), ("Cache-Control", "no-store")] {
        if let Ok(h) = tiny_http::Header::from_bytes(field.as_bytes(), value.as_bytes()) {
            response.add_header(h);
        }
    }
    response
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every file of viewer/ the page loads is embedded: the page's modules, and the vendored
    /// three.js files that viewer/scripts/vendor.mjs lists in FILES.txt.
    #[test]
    fn every_viewer_file_is_embedded_byte_for_byte() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("viewer");
        let mut expected: Vec<String> = std::fs::read_dir(&root)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".html") || n.ends_with(".js"))
            .collect();
        let list = std::fs::read_to_string(root.join("vendor/three/FILES.txt")).unwrap();
        expected.extend(list.lines().skip(1).map(|l| format!("vendor/three/{l}")));
        for name in &expected {
            let embedded = ASSETS.iter().find(|(n, _)| n == name);
            let on_disk = std::fs::read(root.join(name)).unwrap();
            assert_eq!(
                embedded.map(|(_, b)| *b),
                Some(on_disk.as_slice()),
                "viewer/{name} is not embedded (or differs) in src/cli/view.rs"
            );
        }
        assert_eq!(
            ASSETS.len(),
            expected.len(),
            "ASSETS lists files viewer/ does not have"
        );
    }

    #[test]
    fn routes_serve_the_viewer_and_only_the_bake_folder() {
        let dir = Path::new("/data/bakes");
        assert!(matches!(route("/", dir), Route::Asset("index.html", _)));
        assert!(matches!(
            route("/?file=file/a.glb&frame=3", dir),
            Route::Asset("index.html", _)
        ));
        assert!(matches!(
            route("/vendor/three/build/three.module.js", dir),
            Route::Asset(_, _)
        ));
        assert_eq!(
            route("/file/my%20cloth.glb?x", dir),
            Route::File(dir.join("my cloth.glb"))
        );
        for bad in [
            "/file/../etc/passwd",
            "/file/..",
            "/file/%2e%2e",
            "/file/sub/a.glb",
            "/file/a%2Fb",
            "/file/",
            "/file/%zz",
            "/Cargo.toml",
            "/vendor/../main.js",
        ] {
            assert_eq!(route(bad, dir), Route::NotFound, "{bad}");
        }
    }

    #[test]
    fn the_page_url_escapes_the_name() {
        assert_eq!(
            page_url(8000, "my cloth+1.glb", Some(12)),
            "http://127.0.0.1:8000/?file=file/my%20cloth%2B1.glb&frame=12"
        );
        assert_eq!(
            page_url(1, "a.json", None),
            "http://127.0.0.1:1/?file=file/a.json"
        );
        assert_eq!(content_type("x/vat.js"), "text/javascript; charset=utf-8");
    }
}
