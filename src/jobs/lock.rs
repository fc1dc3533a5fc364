//! One writer a job: a lock file in the job's folder, created exclusively and naming its
//! holder, so that two batches writing into one output folder (a retried shard while the
//! first still runs, two unsharded runs) never render the same job at once. The second finds
//! the job [`Acquired::Busy`] and waits for the first's record instead of deleting its files.
//!
//! A lock whose holder is dead (a batch killed with SIGKILL, on this host) is stale and taken
//! over. A holder on another host cannot be checked from here: it counts as alive.

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The lock file's name in a job's folder (never an output name: outputs that start with a
/// dot are not planned, and `.meshtracer-*` names are meshtracer's own).
pub const LOCK_FILE: &str = ".meshtracer-job.lock";

/// The process holding a job's lock.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Holder {
    /// Process id.
    pub pid: u32,
    /// Host name (`/proc/sys/kernel/hostname`), where the pid means something.
    pub host: String,
}

impl Holder {
    /// This process on this host.
    pub fn this_process() -> Holder {
        Holder {
            pid: std::process::id(),
            host: host_name(),
        }
    }

    /// Whether the holder still runs: `Some(false)` only when it is on this host and its
    /// process is gone; `None` when that cannot be known (another host, or no `/proc`).
    pub fn is_alive(&self) -> Option<bool> {
        if self.host != host_name() || !Path::new("/proc/self").exists() {
            return None;
        }
        Some(Path::new("/proc").join(self.pid.to_string()).exists())
    }
}

impl std::fmt::Display for Holder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "pid {} on {}", self.pid, self.host)
    }
}

/// This machine's name, or `unknown` where it cannot be read.
fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|s| s.trim().to_string())
        .ok()
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".to_string())
}

/// A job's lock, held until dropped (the file is removed then; a process killed while holding
/// it leaves a stale lock, which the next batch takes over).
#[derive(Debug)]
pub struct JobLock {
    path: PathBuf,
}

impl Drop for JobLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// What [`acquire`] found.
#[derive(Debug)]
pub enum Acquired {
    /// The lock is this process's until dropped.
    Held(JobLock),
    /// Another live process (or one on another host) holds it.
    Busy(Holder),
}

/// Takes the lock of the job whose folder is `job_dir` (which must exist), or says who holds
/// it. The file appears whole or not at all: the holder is written to a file of this
/// process's own, then hard-linked to [`LOCK_FILE`], which fails if that exists. A stale lock
/// (its holder dead) is moved aside under a name of this process's own before it is removed,
/// so that two processes finding it stale at once never remove a fresh lock.
pub fn acquire(job_dir: &Path) -> std::io::Result<Acquired> {
    let me = Holder::this_process();
    let path = job_dir.join(LOCK_FILE);
    let own = job_dir.join(format!("{LOCK_FILE}.{}.{}", me.pid, me.host));
    let text = serde_json::to_string(&me).map_err(std::io::Error::other)?;
    std::fs::write(&own, text)?;
    let result = take(&path, &own);
    let _ = std::fs::remove_file(&own);
    result
}

/// [`acquire`]'s loop: link `own` to `path`, or report its live holder, or set a stale lock
/// aside and try again.
fn take(path: &Path, own: &Path) -> std::io::Result<Acquired> {
    // A few rounds: each lost one means another process took or freed the lock meanwhile.
    for _ in 0..8 {
        match std::fs::hard_link(own, path) {
            Ok(()) => {
                return Ok(Acquired::Held(JobLock {
                    path: path.to_path_buf(),
                }))
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(e),
        }
        let holder = match read_holder(path) {
            Ok(holder) => holder,
            // Freed since the link failed: try again.
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            Err(e) => return Err(e),
        };
        if let Some(holder) = holder.filter(|h| h.is_alive() != Some(false)) {
            return Ok(Acquired::Busy(holder));
        }
        let mut aside = own.as_os_str().to_owned();
        aside.push(".stale");
        let aside = PathBuf::from(aside);
        if std::fs::rename(path, &aside).is_ok() {
            // What was moved may be a fresh lock taken since it was read: put it back then.
            if read_holder(&aside)
                .ok()
                .flatten()
                .is_some_and(|h| h.is_alive() != Some(false))
            {
                let _ = std::fs::hard_link(&aside, path);
            }
            let _ = std::fs::remove_file(&aside);
        }
    }
    Err(std::io::Error::other(format!(
        "{}: the lock changed hands too often to take",
        path.display()
    )))
}

/// The holder a lock file names; `Ok(None)` when it names none (not this format).
fn read_holder(path: &Path) -> std::io::Result<Option<Holder>> {
    let text = std::fs::read_to_string(path)?;
    Ok(serde_json::from_str(&text).ok())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One holder at a time; dropping the lock frees it; a lock of a dead process on this
    /// host is taken over, one of another host is not.
    #[test]
    fn one_holder_at_a_time_and_stale_locks_are_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        let Acquired::Held(lock) = acquire(dir.path()).unwrap() else {
            panic!("a free lock is taken");
        };
        match acquire(dir.path()).unwrap() {
            Acquired::Busy(holder) => assert_eq!(holder, Holder::this_process()),
            Acquired::Held(_) => panic!("held twice"),
        }
        drop(lock);
        assert!(!dir.path().join(LOCK_FILE).exists());
        let write = |holder: &Holder| {
            std::fs::write(
                dir.path().join(LOCK_FILE),
                serde_json::to_string(holder).unwrap(),
            )
            .unwrap()
        };
        // No process has pid u32::MAX (Linux's pid_max is at most 2^22).
        let dead = Holder {
            pid: u32::MAX,
            host: host_name(),
        };
        write(&dead);
        assert_eq!(dead.is_alive(), Some(false));
        let Acquired::Held(lock) = acquire(dir.path()).unwrap() else {
            panic!("a stale lock is taken over");
        };
        drop(lock);
        let elsewhere = Holder {
            pid: u32::MAX,
            host: format!("{}-elsewhere", host_name()),
        };
        write(&elsewhere);
        assert!(matches!(acquire(dir.path()).unwrap(), Acquired::Busy(h) if h == elsewhere));
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, [LOCK_FILE], "nothing else left behind");
    }
}
