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
///
/// A path that names something other than a file (`/dev/null`, `/dev/stdout`, a named
/// pipe) is written to directly: the rename would replace it with a file, and as root
/// `--out /dev/null` turned the machine's `/dev/null` into a regular file that every
/// later program read garbage from. A symbolic link to a file stays a link: the file it
/// points to is the one replaced.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let error = |cause| WriteError {
        path: path.display().to_string(),
        cause,
    };
    // Through a link to a file, that file is the one replaced (errors still name `path`).
    let mut resolved = None;
    if let Ok(meta) = std::fs::metadata(path) {
        if !meta.is_file() {
            let write = || -> std::io::Result<()> {
                std::fs::OpenOptions::new()
                    .write(true)
                    .open(path)?
                    .write_all(bytes)
            };
            return write().map_err(error);
        }
        if path.is_symlink() {
            resolved = Some(std::fs::canonicalize(path).map_err(error)?);
        }
    }
    let target = resolved.as_deref().unwrap_or(path);
    let dir = target
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = target.file_name().ok_or_else(|| {
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
        std::fs::rename(&tmp, target)
    })();
    if result.is_err() {
        // The write already failed; a leftover temporary file is the lesser problem, and
        // the error reported is the write's.
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(error)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("radiosity-files-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_file_is_replaced_whole_and_no_temporary_file_is_left() {
        let d = scratch("file");
        let path = d.join("out.csv");
        std::fs::write(&path, b"old contents, longer than the new").unwrap();
        write_atomic(&path, b"new").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        let names: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("out.csv")]);
    }

    /// A link stays a link, and the file it names gets the bytes.
    #[cfg(unix)]
    #[test]
    fn a_symbolic_link_stays_a_link() {
        let d = scratch("link");
        let (target, link) = (d.join("target.csv"), d.join("link.csv"));
        std::fs::write(&target, b"old").unwrap();
        std::os::unix::fs::symlink(&target, &link).unwrap();
        write_atomic(&link, b"new").unwrap();
        assert!(link.is_symlink());
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
    }

    /// A named pipe (what `/dev/null` or `/dev/stdout` stand for: not a file) is written
    /// to, not replaced by a file.
    #[cfg(unix)]
    #[test]
    fn a_named_pipe_is_written_to_not_replaced() {
        let d = scratch("fifo");
        let fifo = d.join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            panic!("mkfifo is needed for this test");
        }
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(fifo).unwrap())
        };
        write_atomic(&fifo, b"through the pipe").unwrap();
        // Checked before joining the reader: had the pipe been replaced by a file, the
        // reader would wait for a writer for ever.
        use std::os::unix::fs::FileTypeExt;
        let kind = std::fs::symlink_metadata(&fifo).unwrap().file_type();
        assert!(kind.is_fifo(), "the pipe was replaced: {kind:?}");
        assert_eq!(reader.join().unwrap(), b"through the pipe");
    }
}
