//! `render --preview`: inside a real terminal (a detached tmux session of 80x40 cells) the
//! half blocks show the model's silhouette; in a pseudo-terminal whose other end answers like
//! a sixel, kitty or iTerm2 terminal the picture arrives in that protocol at full resolution;
//! piped, `--preview` prints nothing and `--preview=blocks` prints the blocks anyway.

use crate::common::{root, run, s};
use std::path::Path;
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
    // COLORTERM as a terminal with 24-bit colour sets it (tmux passes it on to the pane).
    let render = format!(
        "COLORTERM=truecolor '{}' render '{}' -o '{}' --width 96 --height 64 --spp 1 -q --preview",
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

/// `render MODEL -o OUT` at 32x16 pixels, 1 spp: 8 lines of half blocks.
fn small_render<'a>(model: &'a Path, out: &'a Path) -> [&'a str; 10] {
    [
        "render",
        s(model),
        "-o",
        s(out),
        "--width",
        "32",
        "--height",
        "16",
        "--spp",
        "1",
    ]
}

#[test]
fn piped_preview_prints_nothing_unless_blocks_are_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let model = root().join("assets/shapes.obj");
    let out = dir.path().join("out.png");
    let base = [&small_render(&model, &out)[..], &["-q"]].concat();
    let auto = run(&[&base[..], &["--preview"]].concat(), true);
    assert!(auto.stdout.is_empty(), "nothing on a pipe");
    // 24-bit colour where COLORTERM says the terminal has it, the 256-colour palette otherwise.
    for (colorterm, escape) in [(Some("truecolor"), "\x1b[38;2;"), (None, "\x1b[38;5;")] {
        let mut command = crate::common::bin();
        command.args([&base[..], &["--preview=blocks"]].concat());
        match colorterm {
            Some(value) => command.env("COLORTERM", value),
            None => command.env_remove("COLORTERM"),
        };
        let blocks = command.output().unwrap();
        assert!(blocks.status.success());
        let text = String::from_utf8(blocks.stdout).unwrap();
        assert_eq!(text.lines().count(), 8, "32x16 pixels are 8 lines: {text}");
        assert!(
            (text.contains('▀') || text.contains('▄')) && text.contains(escape),
            "COLORTERM={colorterm:?}: {text:?}"
        );
    }
}

#[test]
fn a_reader_that_stops_early_spoils_neither_the_files_nor_the_exit_status() {
    // `render ... --preview=blocks 2>&1 | head -3`: the preview and the summary line meet a
    // closed pipe. The render still writes every file (the depth map comes after the preview)
    // and succeeds.
    let dir = tempfile::tempdir().unwrap();
    let model = root().join("assets/shapes.obj");
    let (out, depth) = (dir.path().join("out.png"), dir.path().join("depth.png"));
    let status = crate::common::run_with_readers_gone(
        &[
            &small_render(&model, &out)[..],
            &["--preview=blocks", "--depth-out", s(&depth)],
        ]
        .concat(),
    );
    assert!(status.success(), "{status}");
    assert!(out.is_file() && depth.is_file());
}

/// What the fake terminal at the other end of the pseudo-terminal claims to speak.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Claims {
    Sixel,
    Kitty,
    Iterm,
    Nothing,
}

/// Runs `render --preview` (96x64) on a pseudo-terminal of 80x40 cells that is the child's
/// controlling terminal, answering its queries as a terminal that speaks `claims` would:
/// device attributes (`CSI c`: sixel is attribute 4), the kitty graphics query (`APC G ...
/// a=q`: `OK` for the direct form, an error for the file form, as over SSH), device status
/// (`CSI 5 n`). Returns everything the child wrote and the PNG it saved.
fn fake_terminal(claims: Claims) -> (Vec<u8>, image::RgbaImage) {
    use std::io::{Read, Write};
    use std::os::fd::{FromRawFd, OwnedFd};
    use std::os::unix::process::CommandExt;

    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let (mut master, mut slave) = (0, 0);
    let size = libc::winsize {
        ws_row: 40,
        ws_col: 80,
        ws_xpixel: 800,
        ws_ypixel: 800,
    };
    // SAFETY: openpty writes two new descriptors into the integers passed; each is then owned
    // by exactly one OwnedFd.
    let opened = unsafe {
        libc::openpty(
            &mut master,
            &mut slave,
            std::ptr::null_mut(),
            std::ptr::null(),
            &size,
        )
    };
    assert_eq!(opened, 0, "openpty");
    let (master, slave) = unsafe { (OwnedFd::from_raw_fd(master), OwnedFd::from_raw_fd(slave)) };
    let mut command = crate::common::bin();
    command
        .args([
            "render",
            s(&root().join("assets/shapes.obj")),
            "-o",
            s(&out),
        ])
        .args([
            "--width",
            "96",
            "--height",
            "64",
            "--spp",
            "1",
            "-q",
            "--preview",
        ])
        .env_remove("TERM_PROGRAM")
        .env_remove("LC_TERMINAL")
        .env_remove("KONSOLE_VERSION")
        .env("TERM", "xterm-256color")
        .stdin(slave.try_clone().unwrap())
        .stdout(slave.try_clone().unwrap())
        .stderr(std::process::Stdio::piped());
    if claims == Claims::Iterm {
        command.env("TERM_PROGRAM", "iTerm.app");
    }
    // SAFETY: only async-signal-safe calls between fork and exec: a new session, and the
    // pseudo-terminal (already on descriptor 0) as its controlling terminal, as a terminal
    // emulator does for its shell; `/dev/tty`, where the terminal's answers are read, is it.
    unsafe {
        command.pre_exec(|| {
            if libc::setsid() < 0 || libc::ioctl(0, libc::TIOCSCTTY, 0) < 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let mut child = command.spawn().expect("the binary runs");
    // The parent's copies of the child's end (in `command` too): once closed, reading the
    // master fails as soon as the child exits.
    drop(command);
    drop(slave);
    let mut reader = std::fs::File::from(master.try_clone().unwrap());
    let mut writer = std::fs::File::from(master);
    let (sender, receiver) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut chunk = [0u8; 65536];
        // Once the child has closed its end, reading the master fails (EIO): the end.
        while let Ok(n @ 1..) = reader.read(&mut chunk) {
            if sender.send(chunk[..n].to_vec()).is_err() {
                break;
            }
        }
    });
    let (mut seen, mut answered) = (Vec::new(), 0);
    let start = Instant::now();
    loop {
        match receiver.recv_timeout(Duration::from_millis(100)) {
            Ok(chunk) => seen.extend_from_slice(&chunk),
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
        }
        assert!(
            start.elapsed() < TMUX_TIMEOUT,
            "the preview did not finish; it wrote {:?}",
            String::from_utf8_lossy(&seen)
        );
        // Answer every complete query not answered yet, in the order they were asked.
        while let Some((at, query)) = next_query(&seen[answered..]) {
            let answer: &[u8] = match query {
                Query::DeviceAttributes if claims == Claims::Sixel => b"\x1b[?62;4;22c",
                Query::DeviceAttributes => b"\x1b[?62;22c",
                Query::KittyDirect if claims == Claims::Kitty => b"\x1b_Gi=31;OK\x1b\\",
                Query::KittyDirect => b"",
                Query::KittyFile => b"\x1b_Gi=31;EBADF:no such file here\x1b\\",
                Query::Status => b"\x1b[0n",
            };
            writer.write_all(answer).unwrap();
            answered += at;
        }
    }
    let status = child.wait().unwrap();
    let mut stderr = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut stderr)
        .unwrap();
    assert!(status.success(), "{claims:?}: {stderr}");
    (seen, image::open(&out).unwrap().to_rgba8())
}

/// A terminal query the child wrote.
#[derive(Debug)]
enum Query {
    DeviceAttributes,
    KittyDirect,
    KittyFile,
    Status,
}

/// The first complete query in `bytes` and the offset just past it.
fn next_query(bytes: &[u8]) -> Option<(usize, Query)> {
    let find = |needle: &[u8]| bytes.windows(needle.len()).position(|w| w == needle);
    let candidates = [
        find(b"\x1b[c").map(|at| (at, at + 3, Query::DeviceAttributes)),
        find(b"\x1b[5n").map(|at| (at, at + 4, Query::Status)),
        find(b"\x1b_Gi=31,").and_then(|at| {
            let end = at + bytes[at..].windows(2).position(|w| w == b"\x1b\\")? + 2;
            let query = &bytes[at..end];
            let file = query.windows(4).any(|w| w == b",t=t");
            Some((
                at,
                end,
                if file {
                    Query::KittyFile
                } else {
                    Query::KittyDirect
                },
            ))
        }),
    ];
    candidates
        .into_iter()
        .flatten()
        .min_by_key(|(at, _, _)| *at)
        .map(|(_, end, query)| (end, query))
}

/// The base64 payload between `start` (its end) and the next `end` in `bytes`, decoded.
fn payload(bytes: &[u8], start: &[u8], end: &[u8]) -> Vec<u8> {
    use base64::Engine;
    let at = bytes.windows(start.len()).position(|w| w == start).unwrap() + start.len();
    let len = bytes[at..]
        .windows(end.len())
        .position(|w| w == end)
        .unwrap();
    base64::engine::general_purpose::STANDARD
        .decode(&bytes[at..at + len])
        .unwrap()
}

#[test]
fn a_terminal_that_speaks_sixel_gets_sixels() {
    let (seen, _) = fake_terminal(Claims::Sixel);
    let text = String::from_utf8_lossy(&seen);
    // DCS P1;P2;P3 q, raster attributes, colour registers, sixel data, ST.
    let start = text.find("\x1bP").expect("a DCS sixel sequence");
    let body = &text[start..];
    assert!(
        body[..16].contains('q') && body.contains("\x1b\\"),
        "{body:.80}"
    );
    assert!(body.contains('#'), "colour registers");
    assert!(!text.contains('▀') && !text.contains('▄'), "no half blocks");
}

#[test]
fn a_kitty_terminal_gets_the_full_image_in_the_kitty_protocol() {
    let (seen, png) = fake_terminal(Claims::Kitty);
    // Direct transmission (a remote kitty: the file query was refused) of 32-bit RGBA at the
    // render's own 96x64 pixels, in chunks; placed over 80x27 cells (the half-block fit).
    let text = String::from_utf8_lossy(&seen);
    assert!(
        text.contains("\x1b_Gf=32,a=T,t=d,s=96,v=64,c=80,r=27,m=1;"),
        "{text:.300}"
    );
    let mut raw = payload(&seen, b"m=1;", b"\x1b\\");
    let mut rest = &seen[..];
    let more = b"\x1b_Gm=";
    while let Some(at) = rest.windows(more.len()).position(|w| w == more) {
        rest = &rest[at + more.len()..];
        raw.extend(payload(rest, b";", b"\x1b\\"));
    }
    assert_eq!(raw.len(), 96 * 64 * 4);
    assert_eq!(raw, png.into_raw(), "the pixels sent are the PNG's");
}

#[test]
fn an_iterm_terminal_gets_the_full_image_as_an_inline_png() {
    let (seen, png) = fake_terminal(Claims::Iterm);
    let text = String::from_utf8_lossy(&seen);
    assert!(text.contains("\x1b]1337;File=inline=1;"), "{text:.300}");
    let sent = payload(&seen, b"width=80;height=27:", b"\x07");
    let shown = image::load_from_memory(&sent).unwrap().to_rgba8();
    assert_eq!(shown, png, "the image sent is the render");
}

#[test]
fn a_terminal_without_graphics_gets_half_blocks() {
    let (seen, _) = fake_terminal(Claims::Nothing);
    let text = String::from_utf8_lossy(&seen);
    assert!(text.contains('▄') || text.contains('▀'), "{text:.300}");
    assert!(!text.contains("\x1bP") && !text.contains("\x1b_Gf="));
}

/// `--views` and `batch` show their views or jobs once, together (a contact sheet in memory,
/// written nowhere without `--contact-sheet`), not one picture per view or job.
#[test]
fn views_and_batches_preview_one_sheet_and_write_no_extra_file() {
    let dir = tempfile::tempdir().unwrap();
    let views = dir.path().join("views");
    let model = root().join("assets/shapes.obj");
    let small = ["--width", "64", "--height", "48", "--spp", "1", "-q"];
    let shown = run(
        &[
            &["render", s(&model), "--views", "orbit:4", "-o", s(&views)][..],
            &small,
            &["--preview=blocks"],
        ]
        .concat(),
        true,
    );
    let folder = dir.path().join("models");
    std::fs::create_dir(&folder).unwrap();
    for name in ["shapes.obj", "shapes.mtl", "cornell-box.gltf"] {
        std::fs::copy(root().join("assets").join(name), folder.join(name)).unwrap();
    }
    let jobs = dir.path().join("jobs");
    let batch = run(
        &[
            &["batch", s(&folder), "-o", s(&jobs)][..],
            &small,
            &["--preview=blocks"],
        ]
        .concat(),
        true,
    );
    for (what, out) in [("views", &shown), ("batch", &batch)] {
        let text = String::from_utf8_lossy(&out.stdout);
        let lines = text.lines().count();
        // One picture fits the 80x24 fallback less 2 spare rows; one a view (24 lines of a
        // 64x48 image each) or a job would be 96 or 48 lines.
        assert!((1..=22).contains(&lines), "{what}: {lines} lines");
        assert!(
            text.contains('▀') || text.contains('▄'),
            "{what}: half blocks"
        );
    }
    let mut written: Vec<String> = std::fs::read_dir(&views)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !n.ends_with(".view.json") && n != "transforms.json" && n != "rendered.jsonl")
        .collect();
    written.sort();
    assert_eq!(written, ["000.png", "001.png", "002.png", "003.png"]);
    assert!(!jobs.join("contact-sheet.png").exists());
}
