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

/// Temporary files being written: removed by [`install_signal_cleanup`]'s
/// handler before the process exits on SIGINT/SIGTERM.
static LIVE_TEMPS: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn live_temps() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    LIVE_TEMPS.lock().unwrap_or_else(|e| e.into_inner())
}

/// A temporary file, registered for removal on a signal while it lives.
/// Fields drop in order: the file is removed, then unregistered.
struct LiveTemp {
    path: tempfile::TempPath,
    _registration: Registration,
}

struct Registration(PathBuf);

impl Drop for Registration {
    fn drop(&mut self) {
        live_temps().retain(|p| p != &self.0);
    }
}

/// On SIGINT, SIGTERM or SIGHUP: remove every temporary output file being
/// written, then exit with 128 + the signal number (130, 143, 129). Call once,
/// early in `main`.
#[cfg(unix)]
pub fn install_signal_cleanup() -> io::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])?;
    std::thread::Builder::new()
        .name("volcomp-signals".into())
        .spawn(move || {
            if let Some(signal) = signals.forever().next() {
                // Held until exit: no output is renamed into place meanwhile.
                let live = live_temps();
                for path in live.iter() {
                    let _ = std::fs::remove_file(path);
                }
                std::process::exit(128 + signal);
            }
        })?;
    Ok(())
}

#[cfg(not(unix))]
pub fn install_signal_cleanup() -> io::Result<()> {
    Ok(())
}

/// The temporary output files alive now (for tests of the signal cleanup).
pub fn live_temp_files() -> Vec<PathBuf> {
    live_temps().clone()
}

/// How an output is named in messages: `standard output` for `-`.
pub fn display_name(path: &Path) -> String {
    if is_stdio(path) {
        "standard output".to_string()
    } else {
        path.display().to_string()
    }
}

/// Write `path` atomically with `fill`. When `fill` fails, the destination is not
/// touched and the temporary file is removed; its error is returned as is.
///
/// `-` is standard output. A destination that exists and is not a regular file
/// (a device such as `/dev/null` or `/dev/full`, a named pipe) is written
/// directly: it cannot be replaced by a rename. Every write, the flush and the
/// close are checked.
pub fn write_atomic<E>(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> Result<(), E>,
) -> Result<(), E>
where
    E: From<OutputError>,
{
    let write_error = |source| OutputError::Write {
        path: path.to_path_buf(),
        source,
    };
    if is_stdio(path) {
        let stdout = io::stdout();
        let mut lock = BufWriter::with_capacity(1 << 16, stdout.lock());
        fill(&mut lock)?;
        lock.flush().map_err(|source| OutputError::Write {
            path: PathBuf::from("standard output"),
            source,
        })?;
        return Ok(());
    }
    let special = std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir());
    if special {
        let file = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(write_error)?;
        let mut writer = BufWriter::with_capacity(1 << 16, file);
        fill(&mut writer)?;
        writer.flush().map_err(write_error)?;
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
    live_temps().push(tmp_path.to_path_buf());
    let temp = LiveTemp {
        _registration: Registration(tmp_path.to_path_buf()),
        path: tmp_path,
    };
    let mut writer = BufWriter::with_capacity(1 << 16, file);
    fill(&mut writer)?;
    let file: File = writer
        .into_inner()
        .map_err(|e| write_error(e.into_error()))?;
    // A temporary file is private (0600); the output gets the destination's
    // permissions when it exists, else the usual 0644.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(path)
            .map(|m| m.permissions().mode() & 0o7777)
            .unwrap_or(0o644);
        file.set_permissions(std::fs::Permissions::from_mode(mode))
            .map_err(write_error)?;
    }
    file.sync_all().map_err(write_error)?;
    drop(file);
    // The rename and the unregistration happen under the registry's lock, so a
    // signal handler either removes the temporary file or finds it renamed.
    let LiveTemp {
        path: tmp_path,
        _registration: registration,
    } = temp;
    let persisted = {
        let mut live = live_temps();
        let r = tmp_path.persist(path).map_err(|e| e.error);
        live.retain(|p| p != &registration.0);
        r
    };
    drop(registration);
    persisted.map_err(|source| OutputError::Persist {
        path: path.to_path_buf(),
        source,
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
/// A text file. Bytes that are not UTF-8 are an error naming the line and
/// column of the first one.
pub fn read_to_string(path: &Path) -> Result<String, InputError> {
    let bytes = std::fs::read(path).map_err(|source| InputError {
        path: path.to_path_buf(),
        source,
    })?;
    String::from_utf8(bytes).map_err(|e| {
        let bytes = e.as_bytes();
        let at = e.utf8_error().valid_up_to();
        let before = &bytes[..at];
        let line = before.iter().filter(|b| **b == b'\n').count() + 1;
        let column = at - before.iter().rposition(|b| *b == b'\n').map_or(0, |k| k + 1) + 1;
        InputError {
            path: path.to_path_buf(),
            source: io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "line {line}, column {column}: byte 0x{:02x} is not UTF-8 text (save the file as UTF-8 or ASCII)",
                    bytes[at]
                ),
            ),
        }
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
