//! A command's output files as one unit: written into a private staging
//! folder inside the destination, under an exclusive lock on the
//! destination, and moved into place together only when everything has been
//! written.
//!
//! What this guarantees:
//! - a second run into the same folder while one is writing is refused at
//!   once (before any work), naming the folder;
//! - the destination is created and checked writable before the work starts;
//! - a failed run, an error, Ctrl-C or SIGTERM leaves the destination as it
//!   was (the staging folder, the lock and the folders the run created are
//!   removed; see [`remove_uncommitted`], which an interrupt handler calls);
//! - on success the files this run wrote replace the earlier ones, and the
//!   files the command's previous run here wrote (its manifest,
//!   `.sfs-studio-outputs`) that this run did not (say `noisy8.png` from a
//!   run with noise) are removed, unless this run reads them; nothing else
//!   is ever removed;
//! - a run killed outright (`kill -9`) can leave a staging folder; the next
//!   run into the destination finishes its commit if it had started one
//!   (the `COMMIT` journal, flushed to disk before any move, lists the
//!   moves) and removes it otherwise, so no mix of two runs survives.

use std::fs::{self, File};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::io::{self, IoError};

/// The lock file's name inside a destination folder.
const LOCK_NAME: &str = ".sfs-studio.lock";
/// Prefix of staging folders inside a destination folder.
const STAGING_PREFIX: &str = ".sfs-studio-staging-";
/// The journal a commit writes before it moves anything: the names to move,
/// then a line `-`, then the names to remove.
const JOURNAL_NAME: &str = "COMMIT";
/// The list of files the last run of a command wrote into a folder: only
/// these are ever removed as stale by a later run.
const MANIFEST_NAME: &str = ".sfs-studio-outputs";

/// Staging folders of this process that are not committed, and the lock on
/// committing: an interrupt removes them, but never during a commit.
static PENDING: Mutex<Vec<Pending>> = Mutex::new(Vec::new());

/// What an interrupt removes for one uncommitted stage.
struct Pending {
    staging: PathBuf,
    lock_path: PathBuf,
    /// The folders the run created, deepest first (removed when empty).
    created: Vec<PathBuf>,
}

impl Pending {
    /// Removes the staging folder, the lock file and the folders the run
    /// created (those that are empty).
    fn remove(&self) {
        let _ = fs::remove_dir_all(&self.staging);
        let _ = fs::remove_file(&self.lock_path);
        for dir in &self.created {
            let _ = fs::remove_dir(dir);
        }
    }
}

/// Removes this process's uncommitted staging folders (with their locks
/// and the folders their runs created) and says whether there were any;
/// waits for a commit in progress, so a destination never holds half of a
/// run. For an interrupt handler, which then exits: the stages stay
/// registered, and the lock is kept so that no commit starts after it.
pub fn remove_uncommitted() -> bool {
    let pending = pending();
    for stage in pending.iter() {
        stage.remove();
    }
    let any = !pending.is_empty();
    // Held until the process exits: no stage commits after its folder went.
    std::mem::forget(pending);
    any
}

fn pending() -> std::sync::MutexGuard<'static, Vec<Pending>> {
    PENDING
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Stages a command's output files (see the module documentation).
#[derive(Debug)]
pub struct OutputStage {
    dir: PathBuf,
    staging: PathBuf,
    lock_path: PathBuf,
    /// Held for the stage's life: the exclusive lock on `dir`.
    _lock: File,
    /// The lock file is still ours to remove (not after a commit removed it).
    lock_file_ours: bool,
    /// Folders this run created, deepest first: a failed run removes them.
    created: Vec<PathBuf>,
    /// Every file name the command can write.
    owned: Vec<String>,
    /// Files this run reads (never removed as stale).
    inputs: Vec<PathBuf>,
    /// Registered names, in registration order.
    names: Vec<String>,
}

impl OutputStage {
    /// Starts staging outputs into `dir`: creates it (and its parents),
    /// takes its lock (an error if another run holds it), finishes or
    /// removes what a killed run left there, and creates the staging folder.
    /// `owned` lists every file name the command can write. Errors name the
    /// folder.
    pub fn new(dir: &Path, owned: &[&str]) -> Result<Self, IoError> {
        let create_error = |cause: std::io::Error| IoError::CreateDir {
            path: dir.to_path_buf(),
            cause,
        };
        if dir.exists() && !dir.is_dir() {
            return Err(create_error(std::io::Error::other(
                "it exists and is not a folder",
            )));
        }
        let mut created = Vec::new();
        let mut missing = Some(dir);
        while let Some(d) = missing.filter(|d| !d.as_os_str().is_empty() && !d.exists()) {
            created.push(d.to_path_buf());
            missing = d.parent();
        }
        let remove_created = |created: &[PathBuf]| {
            for d in created {
                let _ = fs::remove_dir(d);
            }
        };
        fs::create_dir_all(dir).map_err(|cause| {
            remove_created(&created);
            create_error(cause)
        })?;
        let lock_path = dir.join(LOCK_NAME);
        let lock = match take_lock(&lock_path) {
            Ok(Some(lock)) => lock,
            Ok(None) => {
                return Err(IoError::Busy {
                    path: dir.to_path_buf(),
                });
            }
            Err(cause) => {
                remove_created(&created);
                return Err(IoError::Write {
                    path: lock_path,
                    cause: format!("cannot lock the output folder: {cause}").into(),
                });
            }
        };
        let staging = dir.join(format!(
            "{STAGING_PREFIX}{}-{}",
            std::process::id(),
            unique_suffix()
        ));
        // Registered before anything else is created, so an interrupt from
        // here on removes all of it.
        pending().push(Pending {
            staging: staging.clone(),
            lock_path: lock_path.clone(),
            created: created.clone(),
        });
        let stage = Self {
            dir: dir.to_path_buf(),
            staging,
            lock_path,
            _lock: lock,
            lock_file_ours: true,
            created,
            owned: owned.iter().map(|s| s.to_string()).collect(),
            inputs: Vec::new(),
            names: Vec::new(),
        };
        recover(dir)?;
        fs::create_dir(&stage.staging).map_err(|cause| IoError::CreateDir {
            path: stage.staging.clone(),
            cause,
        })?;
        Ok(stage)
    }

    /// Files this run reads: never removed as stale outputs, even when
    /// their name is one of the command's (`--confidence out/confidence_used.png`).
    pub fn keep_inputs<'a>(&mut self, paths: impl IntoIterator<Item = &'a Path>) {
        self.inputs
            .extend(paths.into_iter().filter_map(|p| fs::canonicalize(p).ok()));
    }

    /// Registers output `name` (a plain file name) and returns the path to
    /// write it to, inside the staging folder. Registering the same name
    /// twice returns the same path.
    pub fn path(&mut self, name: &str) -> PathBuf {
        // Only the last component: outputs are plain files of `dir`.
        let name = Path::new(name)
            .file_name()
            .map_or_else(|| name.to_string(), |f| f.to_string_lossy().into_owned());
        if !self.names.contains(&name) {
            self.names.push(name.clone());
        }
        self.staging.join(name)
    }

    /// Moves every registered file into place, removes the outputs the
    /// command's previous run in this folder wrote and this one did not
    /// (listed in its manifest; never a file of this run's inputs), and
    /// returns the final paths in registration order. A registered name
    /// that was never written, or whose destination is a folder, is an
    /// error, and then nothing is moved.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, IoError> {
        let mut pending = pending();
        for name in &self.names {
            let staged = self.staging.join(name);
            let target = self.dir.join(name);
            let problem = if !staged.is_file() {
                Some("the output was never written")
            } else if target.is_dir() {
                Some("a folder of that name is in the way")
            } else {
                None
            };
            if let Some(problem) = problem {
                return Err(IoError::Rename {
                    from: staged,
                    to: target,
                    cause: std::io::Error::other(problem),
                });
            }
        }
        let previous = fs::read_to_string(self.dir.join(MANIFEST_NAME)).unwrap_or_default();
        let stale: Vec<&str> = previous
            .lines()
            .filter(|n| self.owned.iter().any(|o| o == n))
            .filter(|n| !self.names.iter().any(|w| w == n))
            .filter(|n| fs::canonicalize(self.dir.join(n)).is_ok_and(|p| !self.inputs.contains(&p)))
            .collect();
        let manifest_path = self.staging.join(MANIFEST_NAME);
        let mut manifest = self.names.join("\n");
        manifest.push('\n');
        let written = fs::write(&manifest_path, manifest);
        let mut journal = self.names.join("\n");
        journal.push('\n');
        if written.is_ok() {
            journal.push_str(MANIFEST_NAME);
            journal.push('\n');
        }
        journal.push_str("-\n");
        for name in &stale {
            journal.push_str(name);
            journal.push('\n');
        }
        write_synced(&self.staging.join(JOURNAL_NAME), &journal)?;
        // From here the journal lets a later run finish what a kill stops.
        let result = apply_journal(&self.dir, &self.staging);
        // The lock file goes before an interrupt may end the process.
        let _ = fs::remove_file(&self.lock_path);
        self.lock_file_ours = false;
        pending.retain(|p| p.staging != self.staging);
        result?;
        self.created.clear(); // the folders now hold this run's output
        Ok(self.names.iter().map(|n| self.dir.join(n)).collect())
    }
}

impl Drop for OutputStage {
    fn drop(&mut self) {
        // After a commit the staging folder is gone already; otherwise the
        // run failed.
        let mut pending = pending();
        if let Some(k) = pending.iter().position(|p| p.staging == self.staging) {
            pending.remove(k);
        }
        let _ = fs::remove_dir_all(&self.staging);
        // The lock file goes while the lock is held (a run that opened it
        // meanwhile sees it replaced and retries, see `take_lock`), and the
        // folders this failed run created go when nothing else is in them.
        if self.lock_file_ours {
            let _ = fs::remove_file(&self.lock_path);
        }
        for dir in &self.created {
            let _ = fs::remove_dir(dir);
        }
    }
}

/// Writes `text` to `path` all at once ([`io::write_atomic`]), so `path` is
/// either absent or complete.
fn write_synced(path: &Path, text: &str) -> Result<(), IoError> {
    io::write_atomic(path, |temporary| {
        fs::write(temporary, text).map_err(|cause| IoError::Write {
            path: temporary.to_path_buf(),
            cause: cause.into(),
        })
    })
}

/// Opens and exclusively locks `path` (created if needed); `None` when
/// another process holds it. The lock counts only if `path` still names the
/// locked file afterwards (its holder removes it before letting go), so a
/// lock taken on a file just removed is retried on the new one.
fn take_lock(path: &Path) -> std::io::Result<Option<File>> {
    for _ in 0..8 {
        let file = File::options()
            .create(true)
            .truncate(false)
            .write(true)
            .open(path)?;
        match file.try_lock() {
            Ok(()) => {}
            Err(fs::TryLockError::WouldBlock) => return Ok(None),
            Err(fs::TryLockError::Error(cause)) => {
                drop(file);
                let _ = fs::remove_file(path);
                return Err(cause);
            }
        }
        if same_file(&file, path) {
            return Ok(Some(file));
        }
    }
    Ok(None)
}

/// Whether `path` names the open `file` (always true where this cannot be
/// told).
fn same_file(file: &File, path: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (file.metadata(), fs::metadata(path)) {
            (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = (file, path);
        true
    }
}

/// Finishes the commit journalled in `staging` and removes the folder.
fn apply_journal(dir: &Path, staging: &Path) -> Result<(), IoError> {
    let journal_path = staging.join(JOURNAL_NAME);
    let journal = fs::read_to_string(&journal_path).map_err(|cause| IoError::Read {
        path: journal_path.clone(),
        cause,
    })?;
    let mut moving = true;
    for line in journal.lines().filter(|l| !l.is_empty()) {
        if line == "-" {
            moving = false;
            continue;
        }
        // Names are plain file names; anything else is not ours.
        if Path::new(line).file_name().map(|f| f.to_string_lossy()) != Some(line.into()) {
            continue;
        }
        let target = dir.join(line);
        if moving {
            let staged = staging.join(line);
            // Moved already by an interrupted earlier attempt: nothing to do.
            if staged.exists() {
                fs::rename(&staged, &target).map_err(|cause| IoError::Rename {
                    from: staged.clone(),
                    to: target.clone(),
                    cause,
                })?;
            }
        } else if target.is_file() {
            let _ = fs::remove_file(&target);
        }
    }
    fs::remove_dir_all(staging).map_err(|cause| IoError::Write {
        path: staging.to_path_buf(),
        cause: cause.into(),
    })
}

/// Finishes or removes the staging folders a killed run left in `dir` (the
/// caller holds the lock, so their owners are gone).
fn recover(dir: &Path) -> Result<(), IoError> {
    let Ok(entries) = fs::read_dir(dir) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        if !name.to_string_lossy().starts_with(STAGING_PREFIX) {
            continue;
        }
        let staging = entry.path();
        if staging.join(JOURNAL_NAME).is_file() {
            apply_journal(dir, &staging)?;
        } else {
            let _ = fs::remove_dir_all(&staging);
        }
    }
    Ok(())
}

/// A suffix that differs between stages of one process and between processes
/// started in the same nanosecond (with the process id).
fn unique_suffix() -> String {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    format!("{nanos:09}-{}", COUNTER.fetch_add(1, Ordering::Relaxed))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;
    use crate::io::{read_npy, write_json, write_npy_f64};
    use tempfile::tempdir;

    fn names_in(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn commits_all_or_nothing() {
        let dir = tempdir().unwrap();
        let out = dir.path().join("out/deep");
        let grid = Grid::filled(2, 2, 1.5);
        let mut stage = OutputStage::new(&out, &["a.npy", "b.json"]).unwrap();
        write_npy_f64(&stage.path("a.npy"), &grid).unwrap();
        write_json(&stage.path("b.json"), &[1, 2]).unwrap();
        assert_eq!(
            names_in(&out).len(),
            2,
            "only the lock and the staging folder yet"
        );
        let done = stage.commit().unwrap();
        assert_eq!(done, vec![out.join("a.npy"), out.join("b.json")]);
        assert_eq!(read_npy(&done[0]).unwrap(), grid);
        assert_eq!(names_in(&out), vec![MANIFEST_NAME, "a.npy", "b.json"]);

        // A failed run (dropped uncommitted) leaves the earlier output alone.
        {
            let mut stage = OutputStage::new(&out, &["a.npy", "b.json"]).unwrap();
            write_json(&stage.path("b.json"), &[3]).unwrap();
        }
        assert_eq!(names_in(&out), vec![MANIFEST_NAME, "a.npy", "b.json"]);
        assert_eq!(
            fs::read_to_string(out.join("b.json")).unwrap(),
            "[\n  1,\n  2\n]\n"
        );

        // A later run that writes less removes the command's stale outputs
        // but leaves other files alone.
        fs::write(out.join("user.txt"), "mine").unwrap();
        let mut stage = OutputStage::new(&out, &["a.npy", "b.json"]).unwrap();
        write_json(&stage.path("b.json"), &[4]).unwrap();
        stage.commit().unwrap();
        assert_eq!(names_in(&out), vec![MANIFEST_NAME, "b.json", "user.txt"]);

        // A name registered but never written fails the commit, moving nothing.
        let mut stage = OutputStage::new(&out, &["a.npy", "b.json"]).unwrap();
        write_json(&stage.path("b.json"), &[5]).unwrap();
        let _ = stage.path("a.npy");
        assert!(stage.commit().is_err());
        assert_eq!(names_in(&out), vec![MANIFEST_NAME, "b.json", "user.txt"]);
        assert_eq!(
            fs::read_to_string(out.join("b.json")).unwrap(),
            "[\n  4\n]\n"
        );
    }

    #[test]
    fn only_files_the_previous_run_wrote_are_removed_and_never_inputs() {
        let dir = tempdir().unwrap();
        let out = dir.path();
        let owned = ["a.txt", "b.txt", "c.txt"];
        // The user's own b.txt, never written by a run: kept.
        fs::write(out.join("b.txt"), "mine").unwrap();
        let mut stage = OutputStage::new(out, &owned).unwrap();
        fs::write(stage.path("a.txt"), "run 1").unwrap();
        fs::write(stage.path("c.txt"), "run 1").unwrap();
        stage.commit().unwrap();
        // Run 2 writes only a.txt and reads c.txt: c.txt stays.
        let mut stage = OutputStage::new(out, &owned).unwrap();
        stage.keep_inputs([out.join("c.txt").as_path()]);
        fs::write(stage.path("a.txt"), "run 2").unwrap();
        stage.commit().unwrap();
        assert_eq!(
            names_in(out),
            vec![MANIFEST_NAME, "a.txt", "b.txt", "c.txt"]
        );
        // Run 3 writes a.txt again: c.txt (run 1's, not an input) is not in
        // run 2's manifest, so it stays too; b.txt never goes.
        let mut stage = OutputStage::new(out, &owned).unwrap();
        fs::write(stage.path("a.txt"), "run 3").unwrap();
        stage.commit().unwrap();
        assert_eq!(fs::read_to_string(out.join("b.txt")).unwrap(), "mine");
        assert!(out.join("c.txt").exists());
    }

    #[test]
    fn second_stage_into_one_folder_is_refused() {
        let dir = tempdir().unwrap();
        let first = OutputStage::new(dir.path(), &[]).unwrap();
        let e = OutputStage::new(dir.path(), &[]).unwrap_err();
        assert!(matches!(e, IoError::Busy { .. }), "{e}");
        assert!(e.to_string().contains(&dir.path().display().to_string()));
        drop(first);
        OutputStage::new(dir.path(), &[]).unwrap();
    }

    #[test]
    fn killed_runs_are_finished_or_removed() {
        let dir = tempdir().unwrap();
        let out = dir.path();
        fs::write(out.join("x.txt"), "old x").unwrap();
        fs::write(out.join("y.txt"), "old y").unwrap();
        fs::write(out.join("z.txt"), "old z").unwrap();
        // A run killed while writing: no journal, so it is dropped.
        let writing = out.join(format!("{STAGING_PREFIX}1-a"));
        fs::create_dir(&writing).unwrap();
        fs::write(writing.join("x.txt"), "half").unwrap();
        // A run killed in its commit after moving y: finished (x moved, z
        // removed as stale).
        let committing = out.join(format!("{STAGING_PREFIX}2-b"));
        fs::create_dir(&committing).unwrap();
        fs::write(committing.join("x.txt"), "new x").unwrap();
        fs::write(committing.join(JOURNAL_NAME), "x.txt\ny.txt\n-\nz.txt\n").unwrap();
        fs::write(out.join("y.txt"), "new y").unwrap();
        drop(OutputStage::new(out, &[]).unwrap());
        assert_eq!(names_in(out), vec!["x.txt", "y.txt"]);
        assert_eq!(fs::read_to_string(out.join("x.txt")).unwrap(), "new x");
        assert_eq!(fs::read_to_string(out.join("y.txt")).unwrap(), "new y");
    }

    #[test]
    fn a_failed_run_leaves_no_folder_it_created() {
        let dir = tempdir().unwrap();
        let out = dir.path().join("new/deeper");
        drop(OutputStage::new(&out, &[]).unwrap());
        assert!(!dir.path().join("new").exists());
        fs::create_dir_all(&out).unwrap();
        drop(OutputStage::new(&out, &[]).unwrap());
        assert!(out.is_dir(), "a folder that was there stays");
        assert!(names_in(&out).is_empty());
    }

    #[test]
    fn destination_that_is_a_file_is_refused_up_front() {
        let dir = tempdir().unwrap();
        let file = dir.path().join("plain-file");
        fs::write(&file, "x").unwrap();
        for dest in [file.clone(), file.join("sub")] {
            let e = OutputStage::new(&dest, &[]).unwrap_err().to_string();
            assert!(e.contains(&dest.display().to_string()), "{e}");
        }
    }
}
