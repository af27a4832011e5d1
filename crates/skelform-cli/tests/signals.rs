//! A signal while a mesh is being written leaves no hidden temporary file behind: the
//! atomic writer's handler removes `.OUT.tmp-PID-N` and the process ends by the signal.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn temporaries(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .expect("read dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.') && n.contains(".tmp-"))
        .collect()
}

/// Starts writing a large ASCII PLY and sends `signal` as soon as its temporary file
/// appears. Returns `None` when the run finished before the file was seen (too fast).
#[cfg(unix)]
fn interrupt(signal: &str, resolution: u32) -> Option<std::process::ExitStatus> {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("big.ply");
    let mut child = Command::new(env!("CARGO_BIN_EXE_skelform"))
        .args(["mesh", &common::example("gyroid.toml"), "-o"])
        .arg(&out)
        .args(["--resolution", &resolution.to_string(), "--ascii", "--quiet"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn skelform");
    let deadline = Instant::now() + Duration::from_secs(20);
    let seen = loop {
        if !temporaries(dir.path()).is_empty() {
            break true;
        }
        if child.try_wait().expect("wait").is_some() || Instant::now() > deadline {
            break false;
        }
        std::thread::sleep(Duration::from_millis(1));
    };
    if !seen {
        let _ = child.kill();
        let _ = child.wait();
        return None;
    }
    let pid = child.id().to_string();
    let sent = Command::new("kill").args([&format!("-{signal}"), &pid]).status().expect("kill");
    assert!(sent.success());
    let status = child.wait().expect("wait");
    if status.success() {
        // The write won the race: it finished before the signal arrived.
        return None;
    }
    assert_eq!(temporaries(dir.path()), Vec::<String>::new(), "after SIG{signal}");
    assert!(!out.exists(), "a partial {} was left", out.display());
    Some(status)
}

#[cfg(unix)]
#[test]
fn a_signal_while_writing_removes_the_temporary_file() {
    use std::os::unix::process::ExitStatusExt;
    for (signal, number) in [("TERM", 15), ("INT", 2), ("HUP", 1)] {
        let status = [96, 160, 256]
            .into_iter()
            .find_map(|r| interrupt(signal, r))
            .unwrap_or_else(|| panic!("never caught the writer of SIG{signal} in the act"));
        // Ended by the signal itself, which a shell reports as 128 + signo.
        assert_eq!(status.signal(), Some(number), "{status:?}");
    }
}
