//! A cache of fitted error models, so that the commands that load a machine
//! do not refit its tables every time.
//!
//! One file per machine file and fit settings, in a cache folder the caller
//! chooses (the command line: `$VOLCOMP_MODEL_CACHE`, else
//! `$XDG_CACHE_HOME/volcomp`, else `~/.cache/volcomp`). The file's name is the
//! FNV-1a hash of the machine file's path and the fit settings; it holds the
//! fitted curves (the `volcomp fit --report` format), the text of every table
//! they were fitted to, the fit settings, and the build of volcomp that fitted
//! them.
//!
//! A cached model is used only when all of that matches: the same volcomp
//! version and executable (size and modification time: a rebuilt volcomp
//! refits), the same settings, and every table of the machine as loaded equal
//! to the cached table's text read again (the same axis, positions, columns and
//! values). The comparison is of the tables themselves, not of a hash of them,
//! so a stale model is never returned. Anything else is a miss: the tables are
//! fitted, and the file is replaced (written atomically). A file that cannot be
//! read or parsed is a miss, never an error. A model is stored only when the
//! table files still hold what was fitted.
//!
//! The cache opens only regular files: a cache file that is a symbolic link,
//! a named pipe or a device is a miss (never followed, never waited on), one
//! larger than [`MAX_CACHE_FILE_BYTES`] is a miss (read no further), and a
//! model is stored under a new name in the cache folder and renamed over the
//! cache file (a link there is replaced, its target never written).
//!
//! Invariant: reads and writes files in the cache folder only, never prints;
//! what happened is returned ([`CacheOutcome`]) for the caller to report.
use super::Machine;
use super::error_model::{ErrorModel, ModelError, ModelOptions};
use super::table::ErrorTable;
use crate::nurbs::{FitOptions, SmemModelFile, fnv1a64};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Version of the cache file's layout.
const FORMAT: u32 = 1;

/// The largest cache file read (a fitted model with its tables' text is a few
/// hundred kB): a larger one is a miss.
pub const MAX_CACHE_FILE_BYTES: u64 = 64 << 20;

/// What the cache did for one load.
#[derive(Clone, Debug, PartialEq)]
pub enum CacheOutcome {
    /// The cached model was used.
    Hit,
    /// No usable cached model (none, another volcomp build or settings, or an
    /// unreadable file): the tables were fitted.
    Fitted,
    /// A model of this machine with these settings was cached, but these
    /// tables changed since: they were fitted again.
    TablesChanged(Vec<PathBuf>),
}

/// The outcome of [`ModelCache::load_or_fit`].
#[derive(Clone, Debug)]
pub struct CacheReport {
    /// Whether the model came from the cache or was fitted (and why).
    pub outcome: CacheOutcome,
    /// The cache file.
    pub file: PathBuf,
    /// Why the fitted model could not be stored (the command still works).
    pub store_error: Option<String>,
}

/// A cache folder of fitted models (see the module doc).
#[derive(Clone, Debug)]
pub struct ModelCache {
    dir: PathBuf,
}

#[derive(Serialize, Deserialize)]
struct Entry {
    format: u32,
    volcomp: String,
    build: String,
    machine: String,
    /// The fit settings, as JSON.
    fit: String,
    tables: Vec<CachedTable>,
    model: SmemModelFile,
}

#[derive(Serialize, Deserialize)]
struct CachedTable {
    axis: String,
    path: PathBuf,
    text: String,
}

impl ModelCache {
    /// The cache in folder `dir` (created when a model is first stored).
    pub fn new(dir: impl Into<PathBuf>) -> ModelCache {
        ModelCache { dir: dir.into() }
    }

    /// The cache folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The cache file of `machine_path` fitted with `fit`.
    pub fn file_for(&self, machine_path: &Path, fit: &FitOptions) -> PathBuf {
        let key = format!("{}\0{}", machine_key(machine_path), fit_key(fit));
        self.dir
            .join(format!("model-{:016x}.json", fnv1a64(key.as_bytes())))
    }

    /// The model of `machine` (loaded from `machine_path`): the cached one when
    /// it was fitted to exactly these tables with these settings by this build,
    /// else fitted now (and stored for next time).
    pub fn load_or_fit(
        &self,
        machine: &Machine,
        machine_path: &Path,
        options: &ModelOptions,
    ) -> Result<(ErrorModel, CacheReport), ModelError> {
        let file = self.file_for(machine_path, &options.fit);
        let build = build_id();
        let outcome = match (&build, self.read(&file)) {
            (Some(build), Some(entry)) if entry.matches(build, machine_path, &options.fit) => {
                let changed = entry.changed_tables(machine);
                if changed.is_empty() {
                    let model =
                        ErrorModel::from_fitted(machine, &entry.model, &file, false, options);
                    if let Ok(model) = model {
                        let report = CacheReport {
                            outcome: CacheOutcome::Hit,
                            file,
                            store_error: None,
                        };
                        return Ok((model, report));
                    }
                    CacheOutcome::Fitted
                } else {
                    CacheOutcome::TablesChanged(changed)
                }
            }
            _ => CacheOutcome::Fitted,
        };
        let model = ErrorModel::from_machine(machine, options)?;
        let store_error = match &build {
            Some(build) => self
                .store(&file, build, machine, machine_path, options, &model)
                .err(),
            None => Some("the path of the volcomp executable is unknown".to_string()),
        };
        Ok((
            model,
            CacheReport {
                outcome,
                file,
                store_error,
            },
        ))
    }

    /// The entry in `file` when it is a regular file (not a link, a pipe or a
    /// device) of at most [`MAX_CACHE_FILE_BYTES`] that parses.
    fn read(&self, file: &Path) -> Option<Entry> {
        use std::io::Read;
        let before = std::fs::symlink_metadata(file).ok()?;
        if !before.file_type().is_file() || before.len() > MAX_CACHE_FILE_BYTES {
            return None;
        }
        let opened = std::fs::File::open(file).ok()?;
        let meta = opened.metadata().ok()?;
        // The file opened is the one looked at (not swapped meanwhile).
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            if (meta.dev(), meta.ino()) != (before.dev(), before.ino()) {
                return None;
            }
        }
        if !meta.is_file() {
            return None;
        }
        let mut text = String::new();
        opened
            .take(MAX_CACHE_FILE_BYTES + 1)
            .read_to_string(&mut text)
            .ok()?;
        if text.len() as u64 > MAX_CACHE_FILE_BYTES {
            return None;
        }
        serde_json::from_str(&text).ok()
    }

    fn store(
        &self,
        file: &Path,
        build: &str,
        machine: &Machine,
        machine_path: &Path,
        options: &ModelOptions,
        model: &ErrorModel,
    ) -> Result<(), String> {
        let mut tables = Vec::new();
        for table in machine.tables.iter().flatten() {
            // What was fitted: the text as read, not the file read again.
            tables.push(CachedTable {
                axis: table.axis.letter().to_string(),
                path: table.path.clone(),
                text: table.text.to_string(),
            });
        }
        let entry = Entry {
            format: FORMAT,
            volcomp: env!("CARGO_PKG_VERSION").to_string(),
            build: build.to_string(),
            machine: machine_key(machine_path),
            fit: fit_key(&options.fit),
            tables,
            model: model.to_model_file(machine).map_err(|e| e.to_string())?,
        };
        std::fs::create_dir_all(&self.dir)
            .map_err(|e| format!("cannot create {}: {e}", self.dir.display()))?;
        let json = serde_json::to_string(&entry).map_err(|e| e.to_string())?;
        write_new_then_rename(&self.dir, file, json.as_bytes())
            .map_err(|e| format!("cannot write {}: {e}", file.display()))
    }
}

impl Entry {
    fn matches(&self, build: &str, machine_path: &Path, fit: &FitOptions) -> bool {
        self.format == FORMAT
            && self.volcomp == env!("CARGO_PKG_VERSION")
            && self.build == build
            && self.machine == machine_key(machine_path)
            && self.fit == fit_key(fit)
    }

    /// The tables of `machine` that the cached text of the same axis does not
    /// reproduce exactly (or that are missing from the cache, or extra in it).
    /// Paths are not compared: the machine file is the same, and a table
    /// reached through another relative path is the same table.
    fn changed_tables(&self, machine: &Machine) -> Vec<PathBuf> {
        let mut changed = Vec::new();
        let loaded: Vec<&ErrorTable> = machine.tables.iter().flatten().collect();
        let axis = |t: &ErrorTable| t.axis.letter().to_string();
        for table in &loaded {
            let cached = self.tables.iter().find(|c| c.axis == axis(table));
            if !cached.is_some_and(|c| same_table(table, &c.text)) {
                changed.push(table.path.clone());
            }
        }
        for c in &self.tables {
            if !loaded.iter().any(|t| c.axis == axis(t)) {
                changed.push(c.path.clone());
            }
        }
        changed
    }
}

/// Write `bytes` to a new file in `dir` and rename it to `file`: whatever
/// `file` was (a link, a pipe, a device) is replaced, never written through.
fn write_new_then_rename(dir: &Path, file: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let mut tmp = tempfile::Builder::new()
        .prefix(".volcomp-cache-")
        .suffix(".tmp")
        .tempfile_in(dir)?;
    tmp.write_all(bytes)?;
    tmp.as_file().sync_all()?;
    tmp.persist(file).map_err(|e| e.error)?;
    Ok(())
}

/// Does `text`, read as `table`'s file, give exactly `table`?
fn same_table(table: &ErrorTable, text: &str) -> bool {
    ErrorTable::parse(text, &table.path, Some(table.axis)).is_ok_and(|t| &t == table)
}

/// The machine file, as an absolute path when it can be resolved.
fn machine_key(path: &Path) -> String {
    std::fs::canonicalize(path)
        .unwrap_or_else(|_| path.to_path_buf())
        .display()
        .to_string()
}

fn fit_key(fit: &FitOptions) -> String {
    serde_json::to_string(fit).unwrap_or_default()
}

/// This build of volcomp: the executable's size and modification time, so
/// that a rebuilt volcomp (whose fits may differ) does not reuse the models of
/// the old one. `None` when the executable cannot be found.
fn build_id() -> Option<String> {
    let exe = std::env::current_exe().ok()?;
    let meta = std::fs::metadata(exe).ok()?;
    let modified = meta
        .modified()
        .ok()?
        .duration_since(std::time::UNIX_EPOCH)
        .ok()?;
    Some(format!("{}:{}", meta.len(), modified.as_nanos()))
}
