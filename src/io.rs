//! Output that is written whole or not at all, and input that names its file.
//!
//! Every file volcomp writes goes through [`write_atomic`]: the content is written
//! to a temporary file in the destination's directory, flushed, and renamed over
//! the destination only when the writer succeeded. `-` means standard output.
//!
//! A command with several outputs opens an [`OutputSet`] first: while it is
//! open, [`write_atomic`] leaves each finished temporary file staged, and
//! [`OutputSet::commit`] renames them all at the end, so a failure anywhere
//! (a second output that cannot be written, an error after the first) replaces
//! none of them. [`check_outputs`] refuses, before anything is computed, an
//! output that is one of the inputs or another output (same device and inode).
//!
//! Output folders, one rule for every option that writes a file: a folder
//! that does not exist is created (as `mkdir -p`) when the outputs are
//! written, and removed again when the command fails before its outputs are
//! in place; a folder that cannot be created (a file stands where a folder
//! of the path should be) is refused by [`check_writable`] before anything is
//! computed.
//!
//! A destination that is a symbolic link is written through: its target is
//! replaced and the link stays (a link to nothing is refused, as `cp` does). A
//! read-only destination (no write bit, or a file the user may not write) is
//! refused, as `cp` does; for every user, root included: the mode bits are the
//! user's statement that the file is not to be replaced.
use std::cell::RefCell;
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
    #[error(
        "{path} is read-only (mode {mode:04o}); volcomp does not replace a write-protected file (make it writable, or name another output)"
    )]
    ReadOnly { path: PathBuf, mode: u32 },
    #[error("{path} cannot be replaced: {source} (name another output)")]
    NotWritable { path: PathBuf, source: io::Error },
    #[error(
        "{path} is a symbolic link to {target}, which does not exist; volcomp does not write through a dangling link (name the file itself)"
    )]
    DanglingLink { path: PathBuf, target: PathBuf },
    #[error(
        "cannot write {path}: {folder} is not a folder, so the output's folder cannot be created"
    )]
    NotAFolder { path: PathBuf, folder: PathBuf },
    #[error("cannot create the folder {folder} of {path}: {source}")]
    CreateFolder {
        path: PathBuf,
        folder: PathBuf,
        source: io::Error,
    },
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

/// On SIGINT, SIGTERM, SIGHUP or SIGXFSZ (a file grew past `ulimit -f`):
/// remove every temporary output file being written, then exit with 128 + the
/// signal number (130, 143, 129, 153). Call once, early in `main`.
#[cfg(unix)]
pub fn install_signal_cleanup() -> io::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM, SIGXFSZ};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP, SIGXFSZ])?;
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
/// close are checked. A symbolic link is written through (its target is
/// replaced); a read-only destination is refused ([`check_writable`]).
///
/// While an [`OutputSet`] is open on this thread, the finished temporary file
/// is staged in it and renamed only by [`OutputSet::commit`].
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
    // Through a symbolic link: the target is what is replaced.
    let destination = check_writable(path)?;
    let dir = folder_of(&destination).to_path_buf();
    let created = create_folders(&dir).map_err(|source| OutputError::CreateFolder {
        path: path.to_path_buf(),
        folder: dir.clone(),
        source,
    })?;
    // Folders made for this output: removed again when it is not written
    // (inside an output set, when the set is dropped without a commit).
    let folders = NewFolders(created);
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
        let mode = std::fs::metadata(&destination)
            .map(|m| m.permissions().mode() & 0o7777)
            .unwrap_or(0o644);
        file.set_permissions(std::fs::Permissions::from_mode(mode))
            .map_err(write_error)?;
    }
    file.sync_all().map_err(write_error)?;
    drop(file);
    let staged = Staged {
        temp,
        destination,
        named: path.to_path_buf(),
        folders,
    };
    let unstaged = STAGED.with(|set| match set.borrow_mut().as_mut() {
        Some(list) => {
            list.push(staged);
            None
        }
        None => Some(staged),
    });
    if let Some(staged) = unstaged {
        persist_all(vec![staged])?
    }
    Ok(())
}

/// A finished temporary file waiting to be renamed over its destination.
struct Staged {
    temp: LiveTemp,
    /// The file replaced (a symbolic link's target).
    destination: PathBuf,
    /// The output as the user named it (for messages).
    named: PathBuf,
    /// The folders created for it (removed if it is not renamed into place).
    folders: NewFolders,
}

/// Folders created for an output, outermost first. Dropped, each one still
/// empty is removed, innermost first; [`NewFolders::keep`] keeps them.
struct NewFolders(Vec<PathBuf>);

impl NewFolders {
    fn keep(mut self) {
        self.0.clear();
    }
}

impl Drop for NewFolders {
    fn drop(&mut self) {
        for folder in self.0.iter().rev() {
            // Fails, as meant, when another output of the set is in it.
            let _ = std::fs::remove_dir(folder);
        }
    }
}

/// The folder a file is in (`.` for a bare name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Create `dir` and its missing parents; the folders created, outermost first.
fn create_folders(dir: &Path) -> io::Result<Vec<PathBuf>> {
    let mut missing = Vec::new();
    let mut at = Some(dir);
    while let Some(folder) = at.filter(|f| !f.as_os_str().is_empty()) {
        if std::fs::symlink_metadata(folder).is_ok() {
            break;
        }
        missing.push(folder.to_path_buf());
        at = folder.parent();
    }
    missing.reverse();
    let mut created = Vec::new();
    for folder in missing {
        match std::fs::create_dir(&folder) {
            Ok(()) => created.push(folder),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists && folder.is_dir() => {}
            Err(e) => {
                drop(NewFolders(created));
                return Err(e);
            }
        }
    }
    Ok(created)
}

/// The nearest folder of `path` (itself or a parent) that exists, and whether
/// it is a folder (not a file standing where a folder should be).
fn nearest_existing(path: &Path) -> (PathBuf, bool) {
    let mut at = folder_of(path);
    loop {
        if let Ok(m) = std::fs::metadata(at) {
            return (at.to_path_buf(), m.is_dir());
        }
        match at.parent() {
            Some(p) if !p.as_os_str().is_empty() => at = p,
            _ => return (PathBuf::from("."), true),
        }
    }
}

/// The absolute, resolved path of a file that may not exist yet, nor its
/// folders: the nearest existing folder resolved (links followed), the rest
/// of the path joined as written. `None` when no folder of it resolves.
pub fn resolved_path(path: &Path) -> Option<PathBuf> {
    if let Ok(real) = std::fs::canonicalize(path) {
        return Some(real);
    }
    let (existing, _) = nearest_existing(path);
    let base = std::fs::canonicalize(&existing).ok()?;
    let rest = if existing == Path::new(".") && !path.starts_with(".") {
        path
    } else {
        path.strip_prefix(&existing).ok()?
    };
    let mut out = base;
    for part in rest.components() {
        match part {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    Some(out)
}

thread_local! {
    /// The outputs staged by [`write_atomic`] while an [`OutputSet`] is open.
    static STAGED: RefCell<Option<Vec<Staged>>> = const { RefCell::new(None) };
}

/// Rename every staged file over its destination, under the registry's lock:
/// a signal handler either removes all the temporary files or finds them all
/// renamed. The destinations' folders were checked when each temporary file was
/// created beside them, so a rename fails only when the file system changes
/// meanwhile; then the outputs renamed before it stay, the rest are removed.
fn persist_all(staged: Vec<Staged>) -> Result<(), OutputError> {
    let mut live = live_temps();
    let mut failure = None;
    for Staged {
        temp,
        destination,
        named,
        folders,
    } in staged
    {
        let LiveTemp {
            path: tmp_path,
            _registration: registration,
        } = temp;
        if failure.is_some() {
            // Dropped: removed (the registry is cleaned below, lock held).
            live.retain(|p| p != &registration.0);
            std::mem::forget(registration);
            drop(tmp_path);
            continue;
        }
        let r = tmp_path.persist(&destination).map_err(|e| e.error);
        live.retain(|p| p != &registration.0);
        std::mem::forget(registration);
        if r.is_ok() {
            folders.keep();
        }
        if let Err(source) = r {
            failure = Some(OutputError::Persist {
                path: named,
                source,
            });
        }
    }
    match failure {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// All the outputs of one command, or none: while it is open, every
/// [`write_atomic`] on this thread stages its finished temporary file, and
/// [`OutputSet::commit`] renames them all. Dropped without a commit (an error
/// on the way), it removes the staged files: no destination is touched.
/// Standard output and devices are written at once (they cannot be staged).
#[must_use = "an output set writes nothing until it is committed"]
pub struct OutputSet {
    /// An inner set (opened while another was open) leaves the staging, and
    /// the commit, to the outer one.
    outer: bool,
}

impl OutputSet {
    /// Open the set: outputs written from now on are staged.
    pub fn begin() -> OutputSet {
        let outer = STAGED.with(|set| {
            let mut set = set.borrow_mut();
            if set.is_none() {
                *set = Some(Vec::new());
                true
            } else {
                false
            }
        });
        OutputSet { outer }
    }

    /// Rename every staged output into place.
    pub fn commit(self) -> Result<(), OutputError> {
        if !self.outer {
            return Ok(());
        }
        let staged = STAGED
            .with(|set| set.borrow_mut().take())
            .unwrap_or_default();
        persist_all(staged)
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        if self.outer {
            // Not committed: the staged temporary files are removed, the
            // last first (a folder made for an earlier output is then empty).
            let staged = STAGED.with(|set| set.borrow_mut().take());
            for output in staged.unwrap_or_default().into_iter().rev() {
                drop(output);
            }
        }
    }
}

/// Can `path` be replaced? Returns the file that would be: `path` itself, or
/// the target of a symbolic link. Refused: a link to nothing, a read-only file
/// (no write bit, for every user; or one the user may not open for writing),
/// a file whose folder cannot be created (a file stands in its way). A folder
/// that does not exist yet is not refused: [`write_atomic`] creates it.
pub fn check_writable(path: &Path) -> Result<PathBuf, OutputError> {
    let link = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
    let destination = if link {
        std::fs::canonicalize(path).map_err(|_| OutputError::DanglingLink {
            path: path.to_path_buf(),
            target: std::fs::read_link(path).unwrap_or_default(),
        })?
    } else {
        path.to_path_buf()
    };
    match std::fs::metadata(&destination) {
        Ok(m) if m.is_file() => {
            #[cfg(unix)]
            {
                use std::os::unix::fs::PermissionsExt;
                let mode = m.permissions().mode() & 0o7777;
                if mode & 0o222 == 0 {
                    return Err(OutputError::ReadOnly {
                        path: path.to_path_buf(),
                        mode,
                    });
                }
            }
            // Opened for writing, not truncated: the permission check of the
            // user (as `cp`), with nothing changed.
            std::fs::OpenOptions::new()
                .write(true)
                .open(&destination)
                .map_err(|source| OutputError::NotWritable {
                    path: path.to_path_buf(),
                    source,
                })?;
        }
        Ok(_) => {}
        Err(_) => {
            // A missing folder is created when the output is written; one
            // that cannot be (a file in its place) is refused now.
            let (folder, is_folder) = nearest_existing(&destination);
            if !is_folder {
                return Err(OutputError::NotAFolder {
                    path: path.to_path_buf(),
                    folder,
                });
            }
        }
    }
    Ok(destination)
}

/// Which file a path names, for telling whether two paths are one file: the
/// device and inode of an existing file (so also through a symbolic or hard
/// link), else the real path of a file still to be created. `None` for
/// standard input/output and for what is not a regular file (a device such
/// as `/dev/null` may be named twice).
#[derive(Debug, Clone, PartialEq, Eq)]
enum Identity {
    Inode(u64, u64),
    Path(PathBuf),
}

fn identity(path: &Path) -> Option<Identity> {
    if is_stdio(path) {
        return None;
    }
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => {
            #[cfg(unix)]
            {
                use std::os::unix::fs::MetadataExt;
                Some(Identity::Inode(m.dev(), m.ino()))
            }
            #[cfg(not(unix))]
            {
                std::fs::canonicalize(path).ok().map(Identity::Path)
            }
        }
        Ok(_) => None,
        Err(_) => resolved_path(path).map(Identity::Path),
    }
}

/// A file of a command, named by its role (`-o`, `--report`, `the program`)
/// for messages.
#[derive(Debug, Clone)]
pub struct NamedPath {
    pub role: String,
    pub path: PathBuf,
}

impl NamedPath {
    pub fn new(role: impl Into<String>, path: impl Into<PathBuf>) -> NamedPath {
        NamedPath {
            role: role.into(),
            path: path.into(),
        }
    }
}

/// An output that is an input or another output.
#[derive(Debug, thiserror::Error)]
pub enum PathClash {
    #[error(
        "{output_role} {output} is {input_role} {input} (the same file): writing it would destroy the input. Name another output"
    )]
    OutputIsInput {
        output_role: String,
        output: String,
        input_role: String,
        input: String,
    },
    #[error(
        "{first_role} {first} and {second_role} {second} are the same file: one output would overwrite the other. Name two different files"
    )]
    TwoOutputs {
        first_role: String,
        first: String,
        second_role: String,
        second: String,
    },
}

/// Refuse an output that is one of the inputs, or another output: the same
/// file by device and inode (through links), or the same path to be created.
/// Standard streams and devices are never a clash.
pub fn check_outputs(inputs: &[NamedPath], outputs: &[NamedPath]) -> Result<(), PathClash> {
    let ids: Vec<Option<Identity>> = outputs.iter().map(|o| identity(&o.path)).collect();
    for (k, (out, id)) in outputs.iter().zip(&ids).enumerate() {
        let Some(id) = id else { continue };
        for input in inputs {
            if identity(&input.path).as_ref() == Some(id) {
                return Err(PathClash::OutputIsInput {
                    output_role: out.role.clone(),
                    output: out.path.display().to_string(),
                    input_role: input.role.clone(),
                    input: input.path.display().to_string(),
                });
            }
        }
        for (first, first_id) in outputs[..k].iter().zip(&ids) {
            if first_id.as_ref() == Some(id) {
                return Err(PathClash::TwoOutputs {
                    first_role: first.role.clone(),
                    first: first.path.display().to_string(),
                    second_role: out.role.clone(),
                    second: out.path.display().to_string(),
                });
            }
        }
    }
    Ok(())
}

/// The most bytes of a cell, word or line a reader's message echoes (as the
/// G-code reader's excerpt): a message stays short however long the input.
pub const ECHO_BYTES: usize = crate::gcode::error::EXCERPT_BYTES;

/// The longest line the line readers take (error tables, plans and
/// measurements, tool tables, `.var` files), bytes: as the G-code reader's.
pub const MAX_LINE_BYTES: usize = 65_536;

/// `text` as a message shows it: whole when short, else its first
/// [`ECHO_BYTES`] (at a character boundary), `…` and its length.
pub fn echo(text: &str) -> std::borrow::Cow<'_, str> {
    if text.len() <= ECHO_BYTES {
        return std::borrow::Cow::Borrowed(text);
    }
    let mut end = ECHO_BYTES;
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    std::borrow::Cow::Owned(format!("{}… ({} bytes)", &text[..end], text.len()))
}

/// The message for a line longer than [`MAX_LINE_BYTES`], `None` for one
/// within it.
pub fn long_line(line: &str) -> Option<String> {
    (line.len() > MAX_LINE_BYTES).then(|| {
        format!(
            "line of {} bytes, longer than volcomp's limit of {MAX_LINE_BYTES} bytes",
            line.len()
        )
    })
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
    fn an_output_set_writes_all_or_none() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.txt"), dir.path().join("b.txt"));
        std::fs::write(&a, "old a").unwrap();
        {
            let set = OutputSet::begin();
            write_file_atomic(&a, b"new a").unwrap();
            // Staged, not yet in place.
            assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
            let r: Result<(), OutputError> = write_atomic(&b, |_| {
                Err(OutputError::Write {
                    path: b.clone(),
                    source: io::Error::other("boom"),
                })
            });
            assert!(r.is_err());
            drop(set);
        }
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
        assert!(!b.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let set = OutputSet::begin();
        write_file_atomic(&a, b"new a").unwrap();
        write_file_atomic(&b, b"new b").unwrap();
        set.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new a");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "new b");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    #[test]
    fn clashing_paths_are_found_through_links() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("in.nc");
        std::fs::write(&input, "x").unwrap();
        let hard = dir.path().join("hard.nc");
        std::fs::hard_link(&input, &hard).unwrap();
        let inputs = [NamedPath::new("the program", &input)];
        let out = |p: &Path| [NamedPath::new("-o", p)];
        assert!(check_outputs(&inputs, &out(&hard)).is_err());
        assert!(check_outputs(&inputs, &out(&dir.path().join("new.nc"))).is_ok());
        assert!(check_outputs(&inputs, &out(Path::new("-"))).is_ok());
        // Two outputs still to be created, named differently.
        let twice = [
            NamedPath::new("-o", dir.path().join("new.nc")),
            NamedPath::new("--report", dir.path().join(".").join("new.nc")),
        ];
        assert!(matches!(
            check_outputs(&inputs, &twice),
            Err(PathClash::TwoOutputs { .. })
        ));
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
