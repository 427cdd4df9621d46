//! `scenebake view`: the local server a browser plays a bake from. Requests go to the binary's
//! server on 127.0.0.1 (a free port), and what it sends is compared with the files on disk.

use crate::common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Stdio};

use common::cli::{bin as scenebake, fails_with};

/// The server, stopped when dropped.
struct Server(Child);

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `scenebake view FILE --no-open --port 0`; returns it and the URL it printed.
fn serve(file: &Path) -> (Server, String) {
    let mut child = scenebake()
        .args(["view", "--no-open", "--port", "0"])
        .arg(file)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    (Server(child), line.trim().to_owned())
}

/// GET `path` from 127.0.0.1:`port` over plain HTTP/1.0: (status, content type, body).
fn get(port: u16, path: &str) -> (u16, String, Vec<u8>) {
    let mut stream = TcpStream::connect(("127.0.0.1", port)).unwrap();
    write!(stream, "GET {path} HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n").unwrap();
    let mut response = Vec::new();
    stream.read_to_end(&mut response).unwrap();
    let split = response
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("an HTTP header");
    let head = String::from_utf8_lossy(&response[..split]).into_owned();
    let status = head.split(' ').nth(1).unwrap().parse().unwrap();
    let content_type = head
        .lines()
        .find_map(|l| {
            l.to_ascii_lowercase()
                .strip_prefix("content-type:")
                .map(|v| v.trim().to_owned())
        })
        .unwrap_or_default();
    (status, content_type, response[split + 4..].to_vec())
}

#[test]
fn view_serves_the_viewer_the_bake_and_its_vat_files_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("lab cloth.glb");
    let exr = dir.path().join("lab cloth.exr");
    let status = scenebake()
        .args([
            "cloth",
            "--preset",
            "lab-cloth",
            "--frames",
            "5",
            "-q",
            "-o",
        ])
        .arg(&glb)
        .arg("--vat")
        .arg(&exr)
        .status()
        .unwrap();
    assert!(status.success());

    let (_server, url) = serve(&dir.path().join("lab cloth.json"));
    let rest = url
        .strip_prefix("http://127.0.0.1:")
        .unwrap_or_else(|| panic!("printed {url:?}"));
    let (port, query) = rest.split_once('/').unwrap();
    let port: u16 = port.parse().unwrap();
    assert_eq!(query, "?file=file/lab%20cloth.json");

    // The page and its modules, as viewer/ holds them.
    let viewer = Path::new(env!("CARGO_MANIFEST_DIR")).join("viewer");
    for (path, file, mime) in [
        ("/", "index.html", "text/html"),
        ("/vat.js", "vat.js", "text/javascript"),
        (
            "/vendor/three/build/three.module.js",
            "vendor/three/build/three.module.js",
            "text/javascript",
        ),
    ] {
        let (status, content_type, body) = get(port, path);
        assert_eq!(status, 200, "{path}");
        assert!(content_type.starts_with(mime), "{path}: {content_type}");
        assert_eq!(body, std::fs::read(viewer.join(file)).unwrap(), "{path}");
    }
    // The bake's files, byte for byte.
    for name in [
        "lab cloth.json",
        "lab cloth.exr",
        "lab cloth.normals.exr",
        "lab cloth.glb",
    ] {
        let (status, _, body) = get(port, &format!("/file/{}", name.replace(' ', "%20")));
        assert_eq!(status, 200, "{name}");
        assert_eq!(
            body,
            std::fs::read(dir.path().join(name)).unwrap(),
            "{name}"
        );
    }
    // Nothing outside the folder, nothing that is not there.
    for path in [
        "/file/..%2F..%2Fetc%2Fpasswd",
        "/file/../Cargo.toml",
        "/file/%2E%2E",
        "/file/missing.glb",
        "/Cargo.toml",
        "/src/cli/view.rs",
    ] {
        assert_eq!(get(port, path).0, 404, "{path}");
    }
}

#[test]
fn view_names_a_missing_or_unplayable_file() {
    fails_with(
        &["view", "--no-open", "no/such/bake.glb"],
        &["no/such/bake.glb", "no such file"],
    );
    fails_with(
        &["view", "--no-open", "Cargo.toml"],
        &["Cargo.toml", ".glb", ".json"],
    );
}
