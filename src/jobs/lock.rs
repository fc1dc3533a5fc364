//! One writer a job: a lock file in the job's folder, created exclusively and naming its
//! holder, so that two batches writing into one output folder (a retried shard while the
//! first still runs, two unsharded runs) never render the same job at once. The second finds
//! the job [`Acquired::Busy`] and waits for the first's record instead of deleting its files.
//!
//! A lock whose holder is dead (a batch killed with SIGKILL, on this host) is stale and taken
//! over. A holder on another host cannot be asked whether it runs; instead a held lock's
//! modification time is renewed every [`HEARTBEAT`], and a batch waiting on another host's
//! lock takes it over once it has seen no renewal for [`LEASE`] (a pod or task killed with
//! SIGKILL or lost with its node, whose retry runs on another host).

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime};

/// How often a held lock's modification time is renewed.
pub const HEARTBEAT: Duration = Duration::from_secs(20);

/// How long a waiting batch watches another host's lock go unrenewed before taking it over:
/// six heartbeats, and twice NFS's longest default attribute cache (`acregmax`, 60 s). The
/// time is the waiter's own clock, and what it watches is whether the modification time
/// changes, not its value, so clocks that disagree between hosts do not matter.
pub const LEASE: Duration = Duration::from_secs(120);

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
/// it leaves a stale lock, which the next batch takes over). While it is held, a thread
/// renews the file's modification time every heartbeat.
#[derive(Debug)]
pub struct JobLock {
    path: PathBuf,
    /// Dropped to stop the heartbeat, which is then joined.
    beating: Option<(mpsc::Sender<()>, std::thread::JoinHandle<()>)>,
}

/// Told when a held lock's renewal fails (the lock file and why), once for each run of
/// failures: while renewals fail, a batch on another host may take the job over after the
/// [`LEASE`] and render it beside this one.
pub type RenewalFailed = Box<dyn Fn(&Path, &std::io::Error) + Send>;

impl JobLock {
    fn new(path: &Path, every: Duration, failed: RenewalFailed) -> JobLock {
        let (stop, stopped) = mpsc::channel::<()>();
        let file = path.to_path_buf();
        let beat = move || {
            let mut failing = false;
            while let Err(mpsc::RecvTimeoutError::Timeout) = stopped.recv_timeout(every) {
                // A failed renewal is retried at the next beat; only six in a row would let a
                // waiting batch take the lock over.
                let renewed = std::fs::File::options()
                    .write(true)
                    .open(&file)
                    .and_then(|f| f.set_modified(SystemTime::now()));
                match renewed {
                    Ok(()) => failing = false,
                    Err(e) if !failing => {
                        failing = true;
                        failed(&file, &e);
                    }
                    Err(_) => {}
                }
            }
        };
        let beating = std::thread::Builder::new()
            .name("job lock heartbeat".into())
            .spawn(beat)
            .ok()
            .map(|thread| (stop, thread));
        JobLock {
            path: path.to_path_buf(),
            beating,
        }
    }
}

impl Drop for JobLock {
    fn drop(&mut self) {
        if let Some((stop, thread)) = self.beating.take() {
            drop(stop);
            let _ = thread.join();
        }
        let _ = std::fs::remove_file(&self.path);
    }
}

/// What a batch waiting on another host's lock has seen of it: the lock file's modification
/// time and since when (on this process's clock) it has not changed.
#[derive(Debug)]
pub struct Watch {
    lease: Duration,
    seen: Option<(Holder, SystemTime, Instant)>,
}

impl Watch {
    /// Watching starts now, with the [`LEASE`].
    pub fn new() -> Watch {
        Watch::with_lease(LEASE)
    }

    fn with_lease(lease: Duration) -> Watch {
        Watch { lease, seen: None }
    }

    /// Whether the lock at `path`, naming `holder`, has gone a lease without a renewal since
    /// this watch first saw it so. The file is opened before its time is read: NFS then asks
    /// the server, where a bare `stat` may answer from its cache.
    fn lapsed(&mut self, path: &Path, holder: &Holder) -> bool {
        let Ok(modified) = std::fs::File::open(path)
            .and_then(|f| f.metadata())
            .and_then(|m| m.modified())
        else {
            return false;
        };
        match &self.seen {
            Some((h, m, since)) if h == holder && *m == modified => since.elapsed() >= self.lease,
            _ => {
                self.seen = Some((holder.clone(), modified, Instant::now()));
                false
            }
        }
    }
}

impl Default for Watch {
    fn default() -> Watch {
        Watch::new()
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
/// (its holder dead, or, with a `watch`, another host's lock gone a lease unrenewed) is moved
/// aside under a name of this process's own before it is removed, so that two processes
/// finding it stale at once never remove a fresh lock.
/// While the lock is held, `failed` is told of renewals that fail.
pub fn acquire(
    job_dir: &Path,
    watch: Option<&mut Watch>,
    failed: RenewalFailed,
) -> std::io::Result<Acquired> {
    acquire_beating(job_dir, watch, HEARTBEAT, failed)
}

/// [`acquire`], the lock renewed `every` so often.
fn acquire_beating(
    job_dir: &Path,
    watch: Option<&mut Watch>,
    every: Duration,
    failed: RenewalFailed,
) -> std::io::Result<Acquired> {
    let me = Holder::this_process();
    let path = job_dir.join(LOCK_FILE);
    let own = job_dir.join(format!("{LOCK_FILE}.{}.{}", me.pid, me.host));
    let text = serde_json::to_string(&me).map_err(std::io::Error::other)?;
    std::fs::write(&own, text)?;
    let result = take(&path, &own, watch);
    let _ = std::fs::remove_file(&own);
    Ok(match result? {
        Taken::Held => Acquired::Held(JobLock::new(&path, every, failed)),
        Taken::Busy(holder) => Acquired::Busy(holder),
    })
}

/// What [`take`] did.
enum Taken {
    Held,
    Busy(Holder),
}

/// [`acquire`]'s loop: link `own` to `path`, or report its live holder, or set a stale lock
/// aside and try again.
fn take(path: &Path, own: &Path, mut watch: Option<&mut Watch>) -> std::io::Result<Taken> {
    // A few rounds: each lost one means another process took or freed the lock meanwhile.
    for _ in 0..8 {
        match std::fs::hard_link(own, path) {
            Ok(()) => return Ok(Taken::Held),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(e),
        }
        let holder = match read_holder(path) {
            Ok(holder) => holder,
            // Freed since the link failed: try again.
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            Err(e) => return Err(e),
        };
        let live = |h: &Holder, watch: &mut Option<&mut Watch>| match h.is_alive() {
            Some(alive) => alive,
            None => !watch.as_mut().is_some_and(|w| w.lapsed(path, h)),
        };
        let stale = match holder {
            Some(h) if live(&h, &mut watch) => return Ok(Taken::Busy(h)),
            stale => stale,
        };
        let mut aside = own.as_os_str().to_owned();
        aside.push(".stale");
        let aside = PathBuf::from(aside);
        if std::fs::rename(path, &aside).is_ok() {
            // What was moved may be a fresh lock taken since it was read (another holder, or
            // a live one of this host): put it back then.
            let moved = read_holder(&aside).ok().flatten();
            if moved.is_some_and(|h| Some(&h) != stale.as_ref() || h.is_alive() == Some(true)) {
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
    use std::sync::atomic::{AtomicUsize, Ordering};

    fn quiet(_: &Path, _: &std::io::Error) {}

    /// A renewal that fails is reported once for each run of failures, with the lock file.
    #[test]
    fn a_failing_renewal_is_reported_once_a_run() {
        static REPORTS: AtomicUsize = AtomicUsize::new(0);
        fn count(path: &Path, e: &std::io::Error) {
            assert!(path.ends_with(LOCK_FILE), "{}", path.display());
            assert_eq!(e.kind(), std::io::ErrorKind::NotFound);
            REPORTS.fetch_add(1, Ordering::SeqCst);
        }
        let dir = tempfile::tempdir().unwrap();
        let every = Duration::from_millis(10);
        let Acquired::Held(lock) =
            acquire_beating(dir.path(), None, every, Box::new(count)).unwrap()
        else {
            panic!("a free lock is taken");
        };
        let path = dir.path().join(LOCK_FILE);
        let wait_for = |n: usize| {
            let start = Instant::now();
            while REPORTS.load(Ordering::SeqCst) < n {
                assert!(start.elapsed() < Duration::from_secs(10), "reported");
                std::thread::sleep(every);
            }
        };
        // Gone from under its holder (removed by hand, or its NFS server lost): renewing it
        // fails at every beat, and is said once.
        let text = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        wait_for(1);
        std::thread::sleep(every * 10);
        assert_eq!(REPORTS.load(Ordering::SeqCst), 1, "once a run of failures");
        // Back, then gone again: a new run of failures, said again.
        std::fs::write(&path, &text).unwrap();
        std::thread::sleep(every * 10);
        std::fs::remove_file(&path).unwrap();
        wait_for(2);
        drop(lock);
    }

    /// One holder at a time; dropping the lock frees it; a lock of a dead process on this
    /// host is taken over, one of another host is not.
    #[test]
    fn one_holder_at_a_time_and_stale_locks_are_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        let Acquired::Held(lock) = acquire(dir.path(), None, Box::new(quiet)).unwrap() else {
            panic!("a free lock is taken");
        };
        match acquire(dir.path(), None, Box::new(quiet)).unwrap() {
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
        let Acquired::Held(lock) = acquire(dir.path(), None, Box::new(quiet)).unwrap() else {
            panic!("a stale lock is taken over");
        };
        drop(lock);
        let elsewhere = Holder {
            pid: u32::MAX,
            host: format!("{}-elsewhere", host_name()),
        };
        write(&elsewhere);
        assert!(
            matches!(acquire(dir.path(), None, Box::new(quiet)).unwrap(), Acquired::Busy(h) if h == elsewhere)
        );
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, [LOCK_FILE], "nothing else left behind");
    }

    /// Writes a lock naming a holder on another host into `dir`.
    fn lock_of_another_host(dir: &Path) -> Holder {
        let holder = Holder {
            pid: 1,
            host: format!("{}-elsewhere", host_name()),
        };
        let text = serde_json::to_string(&holder).unwrap();
        std::fs::write(dir.join(LOCK_FILE), text).unwrap();
        holder
    }

    /// Another host's lock that nothing renews is taken over once a watching batch has seen
    /// it unchanged for a lease, not before; and not without a watch.
    #[test]
    fn another_hosts_lock_is_taken_over_after_a_lease_without_a_heartbeat() {
        let dir = tempfile::tempdir().unwrap();
        let holder = lock_of_another_host(dir.path());
        let mut watch = Watch::with_lease(Duration::from_millis(300));
        let busy = |watch: Option<&mut Watch>| matches!(acquire(dir.path(), watch, Box::new(quiet)).unwrap(), Acquired::Busy(h) if h == holder);
        assert!(busy(Some(&mut watch)), "the lease starts when first seen");
        std::thread::sleep(Duration::from_millis(100));
        assert!(busy(Some(&mut watch)), "within the lease");
        std::thread::sleep(Duration::from_millis(300));
        assert!(busy(None), "without a watch it counts as live");
        let Acquired::Held(lock) = acquire(dir.path(), Some(&mut watch), Box::new(quiet)).unwrap()
        else {
            panic!("a lapsed lock is taken over");
        };
        let text = std::fs::read_to_string(dir.path().join(LOCK_FILE)).unwrap();
        assert_eq!(
            serde_json::from_str::<Holder>(&text).unwrap(),
            Holder::this_process()
        );
        drop(lock);
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert!(names.is_empty(), "nothing left behind: {names:?}");
    }

    /// A lock whose holder renews it is never taken over, however long it is watched; and
    /// this process's own lock is renewed while held.
    #[test]
    fn a_renewed_lock_stays_its_holders() {
        let dir = tempfile::tempdir().unwrap();
        lock_of_another_host(dir.path());
        let path = dir.path().join(LOCK_FILE);
        let (stop, stopped) = mpsc::channel::<()>();
        let renewing = {
            let path = path.clone();
            std::thread::spawn(move || {
                // Ten distinct times a lease: modification times are compared for change.
                let mut t = SystemTime::UNIX_EPOCH;
                while let Err(mpsc::RecvTimeoutError::Timeout) =
                    stopped.recv_timeout(Duration::from_millis(30))
                {
                    t += Duration::from_secs(1);
                    let file = std::fs::File::options().write(true).open(&path).unwrap();
                    file.set_modified(t).unwrap();
                }
            })
        };
        let mut watch = Watch::with_lease(Duration::from_millis(300));
        let start = Instant::now();
        while start.elapsed() < Duration::from_millis(900) {
            let acquired = acquire(dir.path(), Some(&mut watch), Box::new(quiet)).unwrap();
            assert!(
                matches!(acquired, Acquired::Busy(_)),
                "a renewed lock is live"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        drop(stop);
        renewing.join().unwrap();

        std::fs::remove_file(&path).unwrap();
        let Acquired::Held(lock) =
            acquire_beating(dir.path(), None, Duration::from_millis(20), Box::new(quiet)).unwrap()
        else {
            panic!("a free lock is taken");
        };
        let modified = || std::fs::metadata(&path).unwrap().modified().unwrap();
        let first = modified();
        let start = Instant::now();
        while modified() == first {
            assert!(
                start.elapsed() < Duration::from_secs(10),
                "the lock is renewed"
            );
            std::thread::sleep(Duration::from_millis(10));
        }
        drop(lock);
        assert!(
            !path.exists(),
            "dropping the lock stops its heartbeat and removes it"
        );
    }
}
