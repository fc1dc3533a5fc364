//! `render --preview`: inside a real terminal (a detached tmux session of 80x40 cells) the
//! half blocks show the model's silhouette; piped, `--preview` prints nothing and
//! `--preview=blocks` prints the blocks anyway.

mod common;

use common::{root, run, s};
use std::process::Command;
use std::time::{Duration, Instant};

/// Longest the render inside tmux may take (a debug build, 96x64 at 1 spp: about a second).
const TMUX_TIMEOUT: Duration = Duration::from_secs(120);

/// The visible characters of a line captured with `-e` (escape sequences removed).
fn visible(line: &str) -> Vec<char> {
    let mut out = Vec::new();
    let mut chars = line.chars();
    while let Some(c) = chars.next() {
        if c == '\x1b' {
            // CSI: ESC [ parameters final-byte.
            for c in chars.by_ref() {
                if c.is_ascii_alphabetic() {
                    break;
                }
            }
        } else {
            out.push(c);
        }
    }
    out
}

/// A tmux server of its own for this test (its own socket), killed when dropped.
struct Tmux {
    socket: String,
}

impl Tmux {
    fn command(&self) -> Command {
        let mut c = Command::new("tmux");
        c.args(["-L", &self.socket]);
        c
    }
}

impl Drop for Tmux {
    fn drop(&mut self) {
        let _ = self.command().arg("kill-server").output();
    }
}

#[test]
fn preview_in_tmux_shows_the_silhouette() {
    if Command::new("tmux").arg("-V").output().is_err() {
        use std::io::Write;
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED preview_in_tmux_shows_the_silhouette: tmux is not installed (apt-get install tmux)"
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let tmux = Tmux {
        socket: format!("meshtracer-preview-test-{}", std::process::id()),
    };
    let done = "meshtracer-preview-done";
    let render = format!(
        "'{}' render '{}' -o '{}' --width 96 --height 64 --spp 1 -q --preview",
        env!("CARGO_BIN_EXE_meshtracer"),
        s(&root().join("assets/shapes.obj")),
        s(&dir.path().join("out.png")),
    );
    // The session's command: render, signal, then stay open so the pane can be captured.
    let script = format!(
        "{render}; tmux -L {} wait-for -S {done}; sleep 600",
        tmux.socket
    );
    let started = tmux
        .command()
        .args(["new-session", "-d", "-s", "preview", "-x", "80", "-y", "40"])
        .arg(&script)
        .status()
        .expect("tmux runs");
    assert!(started.success(), "tmux new-session failed");
    let mut wait = tmux.command().args(["wait-for", done]).spawn().unwrap();
    let start = Instant::now();
    while wait.try_wait().unwrap().is_none() {
        if start.elapsed() > TMUX_TIMEOUT {
            let _ = wait.kill();
            panic!("the render in tmux did not finish in {TMUX_TIMEOUT:?}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let capture = tmux
        .command()
        .args(["capture-pane", "-p", "-e", "-t", "preview"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&capture.stdout).into_owned();
    let lines: Vec<&str> = text.lines().collect();
    let shown = format!("--- pane\n{}", text.replace('\x1b', "^["));
    assert!(text.contains("\x1b[38;2;"), "24-bit colours: {shown}");
    // 96x64 pixels fit 80 columns: 80x53 pixels, 27 lines of half blocks from the top.
    let picture: Vec<Vec<char>> = lines.iter().take(27).map(|l| visible(l)).collect();
    let block =
        |line: &[char], column: usize| line.get(column).is_some_and(|c| *c == '▀' || *c == '▄');
    let middle = &picture[13];
    let covered = (0..80).filter(|&c| block(middle, c)).count();
    assert!(
        block(middle, 40) && covered > 20,
        "the middle of the picture shows the model: {shown}"
    );
    for (line, column) in [(0, 0), (0, 79), (26, 0), (26, 79)] {
        assert!(
            !block(&picture[line], column),
            "corner ({line}, {column}) shows the terminal's background: {shown}"
        );
    }
    assert!(dir.path().join("out.png").is_file());
}

#[test]
fn piped_preview_prints_nothing_unless_blocks_are_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let model = root().join("assets/shapes.obj");
    let out = dir.path().join("out.png");
    let base = [
        "render",
        s(&model),
        "-o",
        s(&out),
        "--width",
        "32",
        "--height",
        "16",
        "--spp",
        "1",
        "-q",
    ];
    let auto = run(&[&base[..], &["--preview"]].concat(), true);
    assert!(auto.stdout.is_empty(), "nothing on a pipe");
    let blocks = run(&[&base[..], &["--preview=blocks"]].concat(), true);
    let text = String::from_utf8(blocks.stdout).unwrap();
    assert_eq!(text.lines().count(), 8, "32x16 pixels are 8 lines: {text}");
    assert!(text.contains('▀') && text.contains("\x1b[38;2;"));
}
