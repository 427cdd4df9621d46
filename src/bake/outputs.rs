//! The files a job writes, known before it runs, and the check that each can be written: a
//! folder that cannot be written, a path that is a folder, or an existing read-only file is an
//! error before anything is loaded or simulated, not after a long bake.

use std::path::{Path, PathBuf};

use super::cloth::{ClothJob, Switch};
use super::ik::IkJob;
use crate::error::{Error, Result};
use crate::export::vat::vat_paths;
use crate::param::Param;

/// One file a job writes, with the parameter that names it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OutputFile {
    /// The parameter that names the file (`output` for a glTF and its `.bin`).
    pub param: Param,
    /// The file.
    pub path: PathBuf,
}

impl OutputFile {
    /// `path`, named by `param`.
    pub fn new(param: Param, path: impl Into<PathBuf>) -> Self {
        OutputFile {
            param,
            path: path.into(),
        }
    }
}

/// A glTF output and, for a `.gltf`, the `.bin` written beside it.
pub fn gltf_files(output: &Path) -> Vec<OutputFile> {
    let mut files = vec![OutputFile::new(Param::Output, output)];
    let is_gltf = output
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf"));
    if is_gltf {
        let stem = output
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("scene");
        files.push(OutputFile::new(
            Param::Output,
            output.with_file_name(format!("{stem}.bin")),
        ));
    }
    files
}

/// Every file a cloth job writes: its glTF (and `.bin`), its VAT images and JSON, its point
/// caches, its USD layer, its report.
pub fn cloth_outputs(job: &ClothJob) -> Vec<OutputFile> {
    let mut files = gltf_files(&job.output);
    files.extend(job.pc2.iter().map(|p| OutputFile::new(Param::Pc2, p)));
    files.extend(job.mdd.iter().map(|p| OutputFile::new(Param::Mdd, p)));
    files.extend(job.usd.iter().map(|p| OutputFile::new(Param::Usd, p)));
    if let Some(vat) = &job.vat {
        files.push(OutputFile::new(Param::Vat, vat));
        // A malformed --vat path is reported by the bake's own option checks.
        if let Ok((normals, json)) = vat_paths(vat) {
            if job.normals == Switch::On {
                files.push(OutputFile::new(Param::Vat, normals));
            }
            files.push(OutputFile::new(Param::Vat, json));
        }
    }
    files.extend(
        job.report
            .as_ref()
            .map(|r| OutputFile::new(Param::Report, r)),
    );
    files
}

/// Every file an IK job writes: its glTF (and `.bin`) and its report.
pub fn ik_outputs(job: &IkJob) -> Vec<OutputFile> {
    let mut files = gltf_files(&job.output);
    files.extend(
        job.report
            .as_ref()
            .map(|r| OutputFile::new(Param::Report, r)),
    );
    files
}

/// Checks that every file can be written, without writing anything: its folder (or the nearest
/// existing folder above it, where the missing ones will be created) is a folder this process may
/// write in, the path is not a folder, and an existing file is not read-only (an export never
/// replaces a file its owner protected). An empty path is left to the job's own checks.
///
/// # Errors
/// [`Error::Param`] naming the file's parameter, the file and what is wrong.
pub fn check_writable(files: &[OutputFile]) -> Result<()> {
    let mut checked: Vec<PathBuf> = Vec::new();
    for OutputFile { param, path } in files {
        let fail = |what: String| Error::param_value(*param, format!("{}: {what}", path.display()));
        if path.as_os_str().is_empty() {
            // No file given: the job's own checks say so, in their order.
            continue;
        }
        match std::fs::metadata(path) {
            Ok(m) if m.is_dir() => return Err(fail("is a directory, not a file".into())),
            Ok(m) if m.permissions().readonly() => {
                return Err(fail(
                    "exists and is read-only; make it writable or choose another file".into(),
                ))
            }
            _ => {}
        }
        let folder = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        // The nearest existing folder: missing folders below it are created when writing.
        let mut existing = folder.as_path();
        while !existing.exists() {
            match existing.parent() {
                Some(p) if !p.as_os_str().is_empty() => existing = p,
                _ => {
                    existing = Path::new(".");
                    break;
                }
            }
        }
        if !existing.is_dir() {
            return Err(fail(format!(
                "{} is a file, not a directory",
                existing.display()
            )));
        }
        if checked.iter().any(|c| c == existing) {
            continue;
        }
        // The write puts a temporary beside the target and renames it: probe exactly that.
        if let Err(e) = tempfile::Builder::new()
            .prefix(".scenebake-probe.")
            .tempfile_in(existing)
        {
            return Err(fail(format!(
                "cannot write in the directory {} ({})",
                existing.display(),
                os_reason(&e)
            )));
        }
        checked.push(existing.to_path_buf());
    }
    Ok(())
}

/// The operating system's words for `e`, lowercase, without its error number: "permission
/// denied", "read-only file system".
fn os_reason(e: &std::io::Error) -> String {
    let text = e.to_string();
    let text = text.split(" (os error").next().unwrap_or_default();
    let mut chars = text.chars();
    chars
        .next()
        .map(|c| c.to_lowercase().chain(chars).collect())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gltf_has_its_bin_and_a_glb_none() {
        let files = |p: &str| -> Vec<PathBuf> {
            gltf_files(Path::new(p))
                .into_iter()
                .map(|f| f.path)
                .collect()
        };
        assert_eq!(
            files("out/a.b.gltf"),
            [PathBuf::from("out/a.b.gltf"), PathBuf::from("out/a.b.bin")]
        );
        assert_eq!(files("a.GLB"), [PathBuf::from("a.GLB")]);
    }
}
