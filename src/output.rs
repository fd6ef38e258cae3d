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
//!   was (the staging folder is removed; see [`install_interrupt_cleanup`]);
//! - on success the files this run wrote replace the earlier ones and the
//!   command's other outputs left by an earlier run (say `noisy8.png` from a
//!   run with noise) are removed, so the folder holds one run's output;
//! - a run killed outright (`kill -9`, power loss) can leave a staging
//!   folder; the next run into the destination finishes its commit if it had
//!   started one (a `COMMIT` journal lists the moves) and removes it
//!   otherwise, so no mix of two runs survives.

use std::fs::{self, File};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::io::IoError;

/// The lock file's name inside a destination folder.
const LOCK_NAME: &str = ".sfs-studio.lock";
/// Prefix of staging folders inside a destination folder.
const STAGING_PREFIX: &str = ".sfs-studio-staging-";
/// The journal a commit writes before it moves anything: the names to move,
/// then a line `-`, then the names to remove.
const JOURNAL_NAME: &str = "COMMIT";

/// Staging folders of this process that are not committed, and the lock on
/// committing: an interrupt removes them, but never during a commit.
static PENDING: Mutex<Vec<Pending>> = Mutex::new(Vec::new());

/// What an interrupt removes for one uncommitted stage.
struct Pending {
    staging: PathBuf,
    lock_path: PathBuf,
    /// The destination, when the run created it.
    created_dir: Option<PathBuf>,
}

impl Pending {
    /// Removes the staging folder, the lock file and a destination the run
    /// created (if it is empty).
    fn remove(&self) {
        let _ = fs::remove_dir_all(&self.staging);
        let _ = fs::remove_file(&self.lock_path);
        if let Some(dir) = &self.created_dir {
            let _ = fs::remove_dir(dir);
        }
    }
}

/// Makes Ctrl-C and SIGTERM remove this process's uncommitted staging
/// folders and exit with status 130; a commit in progress finishes first, so
/// a destination never holds half of a run. Call once, early, from a
/// command-line program; an error means the handler could not be installed.
pub fn install_interrupt_cleanup() -> Result<(), String> {
    ctrlc::set_handler(|| {
        let pending = PENDING
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        for stage in pending.iter() {
            stage.remove();
        }
        if pending.is_empty() {
            eprintln!("interrupted");
        } else {
            eprintln!("interrupted: the unfinished output was removed");
        }
        std::process::exit(130);
    })
    .map_err(|e| e.to_string())
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
    /// `dir` did not exist before: a failed run removes it again.
    created: bool,
    /// Every file name the command can write; those this run does not write
    /// are removed from `dir` on commit.
    owned: Vec<String>,
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
        let created = !dir.exists();
        fs::create_dir_all(dir).map_err(create_error)?;
        let lock_path = dir.join(LOCK_NAME);
        let lock = match take_lock(&lock_path) {
            Ok(Some(lock)) => lock,
            Ok(None) => {
                return Err(IoError::Busy {
                    path: dir.to_path_buf(),
                });
            }
            Err(cause) => {
                if created {
                    let _ = fs::remove_dir(dir);
                }
                return Err(create_error(cause));
            }
        };
        let mut stage = Self {
            dir: dir.to_path_buf(),
            staging: PathBuf::new(),
            lock_path,
            _lock: lock,
            created,
            owned: owned.iter().map(|s| s.to_string()).collect(),
            names: Vec::new(),
        };
        recover(dir)?;
        let staging = dir.join(format!(
            "{STAGING_PREFIX}{}-{}",
            std::process::id(),
            unique_suffix()
        ));
        fs::create_dir(&staging).map_err(|cause| IoError::CreateDir {
            path: staging.clone(),
            cause,
        })?;
        pending().push(Pending {
            staging: staging.clone(),
            lock_path: stage.lock_path.clone(),
            created_dir: created.then(|| dir.to_path_buf()),
        });
        stage.staging = staging;
        Ok(stage)
    }

    /// The folder the outputs go to.
    pub fn dir(&self) -> &Path {
        &self.dir
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

    /// Moves every registered file into place, removes the command's other
    /// outputs left by an earlier run, and returns the final paths in
    /// registration order. A registered name that was never written is an
    /// error, and then nothing is moved.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, IoError> {
        let mut pending = pending();
        for name in &self.names {
            let staged = self.staging.join(name);
            if !staged.is_file() {
                return Err(IoError::Rename {
                    from: staged,
                    to: self.dir.join(name),
                    cause: std::io::Error::other("the output was never written"),
                });
            }
        }
        let stale: Vec<&String> = self
            .owned
            .iter()
            .filter(|o| !self.names.contains(o))
            .collect();
        let mut journal = self.names.join("\n");
        journal.push_str("\n-\n");
        for name in &stale {
            journal.push_str(name);
            journal.push('\n');
        }
        let journal_path = self.staging.join(JOURNAL_NAME);
        fs::write(&journal_path, journal).map_err(|cause| IoError::Write {
            path: journal_path.clone(),
            cause: cause.into(),
        })?;
        // From here the journal lets a later run finish what a kill stops.
        let result = apply_journal(&self.dir, &self.staging);
        pending.retain(|p| p.staging != self.staging);
        result?;
        self.created = false; // the folder now holds this run's output
        Ok(self.names.iter().map(|n| self.dir.join(n)).collect())
    }
}

impl Drop for OutputStage {
    fn drop(&mut self) {
        // After a commit the folder is gone already; otherwise the run failed.
        let mut pending = pending();
        if let Some(k) = pending.iter().position(|p| p.staging == self.staging) {
            pending.remove(k);
            let _ = fs::remove_dir_all(&self.staging);
        }
        // The lock file goes while the lock is held (a run that opened it
        // meanwhile sees it replaced and retries, see `take_lock`), and a
        // folder this failed run created goes when nothing else is in it.
        let _ = fs::remove_file(&self.lock_path);
        if self.created {
            let _ = fs::remove_dir(&self.dir);
        }
    }
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
            Err(fs::TryLockError::Error(cause)) => return Err(cause),
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
        assert_eq!(names_in(&out), vec!["a.npy", "b.json"]);

        // A failed run (dropped uncommitted) leaves the earlier output alone.
        {
            let mut stage = OutputStage::new(&out, &["a.npy", "b.json"]).unwrap();
            write_json(&stage.path("b.json"), &[3]).unwrap();
        }
        assert_eq!(names_in(&out), vec!["a.npy", "b.json"]);
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
        assert_eq!(names_in(&out), vec!["b.json", "user.txt"]);

        // A name registered but never written fails the commit, moving nothing.
        let mut stage = OutputStage::new(&out, &["a.npy", "b.json"]).unwrap();
        write_json(&stage.path("b.json"), &[5]).unwrap();
        let _ = stage.path("a.npy");
        assert!(stage.commit().is_err());
        assert_eq!(names_in(&out), vec!["b.json", "user.txt"]);
        assert_eq!(
            fs::read_to_string(out.join("b.json")).unwrap(),
            "[\n  4\n]\n"
        );
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
        let out = dir.path().join("new");
        drop(OutputStage::new(&out, &[]).unwrap());
        assert!(!out.exists());
        fs::create_dir(&out).unwrap();
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
