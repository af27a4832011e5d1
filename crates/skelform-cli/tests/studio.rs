//! `skelform studio` from the command line: the URL it prints answers with the token and
//! refuses without it; a scene that cannot be read is an input error (exit 2).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};

fn status_of(addr: &str, target: &str) -> String {
    let mut s = TcpStream::connect(addr).unwrap();
    write!(s, "GET {target} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).unwrap();
    text.lines().next().unwrap_or_default().to_string()
}

/// Ends the studio when the test ends, passing or not.
struct Killed(std::process::Child);
impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn the_printed_url_opens_the_page_and_nothing_opens_without_its_token() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("torus.toml");
    std::fs::copy(concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/torus.toml"), &scene)
        .unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_skelform"))
        .args(["studio", scene.to_str().unwrap(), "--port", "0", "--no-open"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut child = Killed(child);
    let mut line = String::new();
    BufReader::new(child.0.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let url = line.trim().strip_prefix("skelform studio: ").expect(&line).to_string();
    let rest = url.strip_prefix("http://127.0.0.1:").expect(&url);
    let (port, token) = rest.split_once("/?token=").expect(&url);
    assert_eq!(token.len(), 32);
    let addr = format!("127.0.0.1:{port}");
    assert!(status_of(&addr, &format!("/?token={token}")).contains("200"));
    assert!(status_of(&addr, "/").contains("403"));
}

#[test]
fn a_scene_that_cannot_be_read_is_an_input_error() {
    let o = Command::new(env!("CARGO_BIN_EXE_skelform"))
        .args(["studio", "no/such/scene.toml", "--no-open"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no/such/scene.toml"));
}
