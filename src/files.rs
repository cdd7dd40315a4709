//! Writing output files so that they are never partial.

use std::io::Write;
use std::path::Path;

/// Why an output file could not be written. Its `Display` names the file.
#[derive(Debug, thiserror::Error)]
#[error("{path}: cannot write: {cause}")]
pub struct WriteError {
    pub path: String,
    /// The operating system's error (in the message, so not also a `source()`).
    pub cause: std::io::Error,
}

/// Writes `bytes` to `path` atomically: a temporary file beside it, then a rename, so a
/// failure never leaves a partial file and never clobbers the old one half-way.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let error = |cause| WriteError {
        path: path.display().to_string(),
        cause,
    };
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path.file_name().ok_or_else(|| {
        error(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the path has no file name",
        ))
    })?;
    let tmp = dir.join(format!(
        ".{}.tmp{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    let result = (|| -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        // The write already failed; a leftover temporary file is the lesser problem, and
        // the error reported is the write's.
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(error)
}
