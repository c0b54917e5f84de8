//! Output that is written whole or not at all, and input that names its file.
//!
//! Every file volcomp writes goes through [`write_atomic`]: the content is written
//! to a temporary file in the destination's directory, flushed, and renamed over
//! the destination only when the writer succeeded. `-` means standard output.
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("cannot create a temporary file next to {path}: {source}")]
    Create { path: PathBuf, source: io::Error },
    #[error("cannot write {path}: {source}")]
    Write { path: PathBuf, source: io::Error },
    #[error("cannot move the finished output into place at {path}: {source}")]
    Persist { path: PathBuf, source: io::Error },
}

/// Is this path the conventional "standard stream" marker `-`?
pub fn is_stdio(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// Write `path` atomically with `fill`. When `fill` fails, the destination is not
/// touched and the temporary file is removed; its error is returned as is.
pub fn write_atomic<E>(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> Result<(), E>,
) -> Result<(), E>
where
    E: From<OutputError>,
{
    if is_stdio(path) {
        let stdout = io::stdout();
        let mut lock = BufWriter::new(stdout.lock());
        fill(&mut lock)?;
        lock.flush().map_err(|source| OutputError::Write {
            path: path.to_path_buf(),
            source,
        })?;
        return Ok(());
    }
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let tmp = tempfile::Builder::new()
        .prefix(".volcomp-")
        .suffix(".tmp")
        .tempfile_in(&dir)
        .map_err(|source| OutputError::Create {
            path: path.to_path_buf(),
            source,
        })?;
    let (file, tmp_path) = tmp.into_parts();
    let mut writer = BufWriter::with_capacity(1 << 16, file);
    fill(&mut writer)?;
    let file: File = writer.into_inner().map_err(|e| OutputError::Write {
        path: path.to_path_buf(),
        source: e.into_error(),
    })?;
    // A temporary file is private (0600); the output gets the destination's
    // permissions when it exists, else the usual 0644.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(path)
            .map(|m| m.permissions().mode() & 0o7777)
            .unwrap_or(0o644);
        file.set_permissions(std::fs::Permissions::from_mode(mode))
            .map_err(|source| OutputError::Write {
                path: path.to_path_buf(),
                source,
            })?;
    }
    file.sync_all().map_err(|source| OutputError::Write {
        path: path.to_path_buf(),
        source,
    })?;
    drop(file);
    tmp_path.persist(path).map_err(|e| OutputError::Persist {
        path: path.to_path_buf(),
        source: e.error,
    })?;
    Ok(())
}

/// Convenience: write a whole string or byte buffer atomically.
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    write_atomic(path, |w| {
        w.write_all(bytes).map_err(|source| OutputError::Write {
            path: path.to_path_buf(),
            source,
        })
    })
}

/// Write a value as pretty JSON atomically.
pub fn write_json_atomic<T: serde::Serialize>(path: &Path, value: &T) -> Result<(), OutputError> {
    let mut text = serde_json::to_string_pretty(value).expect("report types serialise");
    text.push('\n');
    write_file_atomic(path, text.as_bytes())
}

/// Read a whole file, naming it in the error.
pub fn read_to_string(path: &Path) -> Result<String, InputError> {
    std::fs::read_to_string(path).map_err(|source| InputError {
        path: path.to_path_buf(),
        source,
    })
}

#[derive(Debug, thiserror::Error)]
#[error("cannot read {path}: {source}")]
pub struct InputError {
    pub path: PathBuf,
    pub source: io::Error,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_writer_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.txt");
        let r: Result<(), OutputError> = write_atomic(&out, |w| {
            w.write_all(b"partial").unwrap();
            Err(OutputError::Write {
                path: out.clone(),
                source: io::Error::other("boom"),
            })
        });
        assert!(r.is_err());
        assert!(!out.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[cfg(unix)]
    #[test]
    fn new_output_is_world_readable() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("new.txt");
        write_file_atomic(&out, b"x").unwrap();
        let mode = std::fs::metadata(&out).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o644);
    }

    #[test]
    fn successful_writer_replaces_file() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.txt");
        std::fs::write(&out, "old").unwrap();
        write_file_atomic(&out, b"new").unwrap();
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "new");
    }
}
