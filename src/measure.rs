//! Wall time and peak memory of named steps, for `--stats`, `meshtracer bench` and the
//! summary line.

use std::time::{Duration, Instant};

/// The process's peak resident memory so far (Linux: `VmHWM` of /proc/self/status); `None`
/// where it cannot be read.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// One measured step: its name, wall time and the process's peak memory when it ended.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    /// What was done ("ploc", "render", ...).
    pub name: &'static str,
    /// Wall time.
    pub time: Duration,
    /// Peak resident memory of the process at the end of the step (`None` off Linux).
    pub peak_memory: Option<u64>,
}

/// Times consecutive steps: each [`Steps::mark`] closes the step begun at the previous mark.
#[derive(Clone, Debug)]
pub struct Steps {
    list: Vec<Step>,
    since: Instant,
}

impl Default for Steps {
    fn default() -> Self {
        Self::new()
    }
}

impl Steps {
    /// Starts timing the first step now.
    pub fn new() -> Self {
        Self {
            list: Vec::new(),
            since: Instant::now(),
        }
    }

    /// Ends the current step under `name` and starts the next one.
    pub fn mark(&mut self, name: &'static str) {
        let now = Instant::now();
        self.list.push(Step {
            name,
            time: now - self.since,
            peak_memory: peak_memory_bytes(),
        });
        self.since = now;
    }

    /// The steps ended so far, in order.
    pub fn list(&self) -> &[Step] {
        &self.list
    }

    /// The sum of their times.
    pub fn total(&self) -> Duration {
        self.list.iter().map(|s| s.time).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_are_consecutive_and_sum_to_the_total() {
        let mut steps = Steps::new();
        std::thread::sleep(Duration::from_millis(2));
        steps.mark("a");
        steps.mark("b");
        let names: Vec<_> = steps.list().iter().map(|s| s.name).collect();
        assert_eq!(names, ["a", "b"]);
        assert!(steps.list()[0].time >= Duration::from_millis(2));
        assert_eq!(steps.total(), steps.list()[0].time + steps.list()[1].time);
        #[cfg(target_os = "linux")]
        assert!(steps.list()[1].peak_memory.unwrap_or(0) > 0);
    }
}
