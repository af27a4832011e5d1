//! `skelform studio`: the design studio's server, with the URL printed and a browser opened.

use std::net::IpAddr;
use std::path::PathBuf;

use anyhow::anyhow;
use clap::Args;

use crate::{Failure, input, runtime};

#[derive(Args)]
pub struct StudioArgs {
    /// The scene file (TOML) to edit; saving writes it back.
    scene: PathBuf,
    /// The port to listen on; 0 picks a free one.
    #[arg(long, default_value_t = 8765)]
    port: u16,
    /// Do not open a browser.
    #[arg(long)]
    no_open: bool,
    /// The address to listen on (default 127.0.0.1). Another address lets other machines
    /// reach the studio; the session token still guards it.
    #[arg(long)]
    host: Option<IpAddr>,
}

pub fn studio(a: StudioArgs) -> Result<(), Failure> {
    let mut settings = skelform_studio::Settings { port: a.port, ..Default::default() };
    if let Some(host) = a.host {
        if !host.is_loopback() {
            errln!(
                "warning: listening on {host}: other machines can reach the studio (anyone with the URL's token can edit and save the scene)"
            );
        }
        settings.host = host;
    }
    let open = !a.no_open;
    let result = skelform_studio::run(&a.scene, settings, |url, _| {
        // Printed before anything else so that scripts (and tests) can read it.
        let _ = crate::console::out(format_args!("skelform studio: {url}\n"));
        if open {
            open_browser(url);
        }
    });
    result.map_err(|e| match e {
        skelform_studio::StudioError::Scene { .. } => input(anyhow!("{e}")),
        e => runtime(anyhow!("{e}")),
    })
}

/// Opens `url` in the desktop's browser when there is one: `$BROWSER`, or the platform's
/// opener where a display is there to show it. Failure is not an error: the URL is printed.
fn open_browser(url: &str) {
    use std::process::{Command, Stdio};
    let opener = if let Some(b) = std::env::var_os("BROWSER").filter(|b| !b.is_empty()) {
        Some(b)
    } else if cfg!(target_os = "macos") {
        Some("open".into())
    } else if cfg!(windows) {
        Some("explorer".into())
    } else if std::env::var_os("DISPLAY").is_some() || std::env::var_os("WAYLAND_DISPLAY").is_some()
    {
        Some("xdg-open".into())
    } else {
        None
    };
    if let Some(o) = opener {
        let _ = Command::new(o)
            .arg(url)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn();
    }
}
