//! The skelform design studio: a local web page on which a skeletal scene is edited and its
//! surface re-meshed at once (the interactive design of the dissertation's chapter 2).
//!
//! [`Studio::bind`] opens the scene and a listening socket; [`Studio::serve`] answers the
//! page, its assets (embedded in the binary: nothing is fetched from the internet) and one
//! WebSocket per page. The scene is held as a `toml_edit` document, so that saving keeps the
//! file's comments and layout; every edit is applied to a copy and checked by
//! [`skelform::Scene::parse`] before it replaces the document, so an invalid edit changes
//! nothing.
//!
//! # Security
//! The server binds loopback unless told otherwise, and requires a random session token
//! (the `token` query parameter or the `x-skelform-token` header) on every request,
//! including the page and the WebSocket; a request with an `Origin` header must come from
//! the served origin. Messages and bodies are bounded ([`Settings::max_message`]). The only
//! files written are the scene file (on save) and exports named by a plain file name in the
//! scene's folder; no file is read but the scene.
//!
//! # Protocol
//! Text frames from the page are JSON edits with a sequence number, e.g.
//! `{"seq":7,"op":"set","path":["skeleton","segment",3,"radius"],"value":0.2}`; see
//! `docs/STUDIO.md` in the repository. The server answers with a JSON `state` (document revision, skeleton,
//! settings) after every accepted change, an `error` for a refused one, and binary mesh
//! frames ([`mesher::encode`]) that carry the revision they are of.
#![warn(missing_docs)]

pub mod edit;
pub mod mesher;
mod server;
pub mod slice;

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use server::Studio;

/// What the studio can be asked to do differently.
#[derive(Clone, Debug)]
pub struct Settings {
    /// The address to listen on: loopback by default. Anything else lets other machines
    /// reach the page (the token still guards it).
    pub host: IpAddr,
    /// The port; 0 picks a free one.
    pub port: u16,
    /// The largest WebSocket message or request body accepted, in bytes.
    pub max_message: usize,
    /// The coarse surface's cell, as a multiple of the scene's (4: a quarter of the
    /// resolution, about 1/64 of the work).
    pub coarse_factor: f64,
    /// How many edits undo remembers.
    pub undo_limit: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            host: IpAddr::V4(Ipv4Addr::LOCALHOST),
            port: 0,
            max_message: 1 << 20,
            coarse_factor: 4.0,
            undo_limit: 1000,
        }
    }
}

impl Settings {
    /// Refuses settings that cannot work: a coarse factor below 1 or not finite, a message
    /// limit under 64 KiB (an edit of a large polygon would not fit), no undo.
    pub fn check(&self) -> Result<(), StudioError> {
        let bad = |message: String| Err(StudioError::Edit(message));
        if !(self.coarse_factor.is_finite() && self.coarse_factor >= 1.0) {
            return bad(format!("coarse_factor {} (at least 1)", self.coarse_factor));
        }
        if self.max_message < 1 << 16 {
            return bad(format!("max_message {} (at least 65536 bytes)", self.max_message));
        }
        if self.undo_limit == 0 {
            return bad("undo_limit 0 (at least 1)".into());
        }
        Ok(())
    }
}

/// Why the studio could not start, or an edit was refused.
#[derive(Debug, thiserror::Error)]
pub enum StudioError {
    /// The scene file could not be read or is not TOML.
    #[error("{path}: {message}")]
    Scene {
        /// The file.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// An edit that cannot be applied (no such element, not a value, an invalid scene).
    #[error("{0}")]
    Edit(String),
    /// The socket, the random token or a file write failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

/// A session token: 16 random bytes as 32 hex digits.
pub fn new_token() -> Result<String, StudioError> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes).map_err(|e| std::io::Error::other(e.to_string()))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// The scene file and its folder, resolved once: the folder is the only place the studio
/// writes to.
#[derive(Clone, Debug)]
pub(crate) struct Place {
    pub file: PathBuf,
    pub dir: PathBuf,
}

impl Place {
    fn new(scene: &Path) -> Result<Place, StudioError> {
        let file = scene.canonicalize().map_err(|e| StudioError::Scene {
            path: scene.display().to_string(),
            message: e.to_string(),
        })?;
        let dir = file.parent().map(Path::to_path_buf).ok_or_else(|| StudioError::Scene {
            path: scene.display().to_string(),
            message: "has no folder".into(),
        })?;
        Ok(Place { file, dir })
    }

    /// A file for an export: a plain name (no folder, no `..`, not hidden) with the
    /// format's extension, in the scene's folder.
    pub fn export_path(&self, name: &str, extension: &str) -> Result<PathBuf, StudioError> {
        use std::path::Component;
        let p = Path::new(name);
        let mut parts = p.components();
        let plain = matches!((parts.next(), parts.next()), (Some(Component::Normal(_)), None));
        if !plain || name.starts_with('.') || name.contains(['/', '\\']) {
            return Err(StudioError::Edit(format!(
                "'{name}' is not a plain file name in the scene's folder"
            )));
        }
        if p.extension().and_then(|e| e.to_str()) != Some(extension) {
            return Err(StudioError::Edit(format!("'{name}' does not end in .{extension}")));
        }
        let path = self.dir.join(p);
        // The writers write through a symbolic link to its target, which may lie anywhere.
        if std::fs::symlink_metadata(&path).is_ok_and(|m| m.file_type().is_symlink()) {
            return Err(StudioError::Edit(format!(
                "'{name}' is a symbolic link; the studio writes only plain files in the scene's folder"
            )));
        }
        Ok(path)
    }
}

/// Runs the studio on a runtime of its own until the process ends: what the command line
/// calls. `ready` gets the page's URL (with the token) once the socket listens.
pub fn run(
    scene: &Path,
    settings: Settings,
    ready: impl FnOnce(&str, SocketAddr),
) -> Result<(), StudioError> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .thread_name("skelform-studio")
        .build()?;
    runtime.block_on(async move {
        let studio = Studio::bind(scene, settings).await?;
        ready(&studio.url(), studio.addr());
        studio.serve().await
    })
}

pub(crate) type Shared = Arc<server::State>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_that_cannot_work_are_refused_and_tokens_differ() {
        assert!(Settings::default().check().is_ok());
        for s in [
            Settings { coarse_factor: 0.5, ..Settings::default() },
            Settings { coarse_factor: f64::NAN, ..Settings::default() },
            Settings { max_message: 10, ..Settings::default() },
            Settings { undo_limit: 0, ..Settings::default() },
        ] {
            assert!(s.check().is_err(), "{s:?}");
        }
        let (a, b) = (new_token().unwrap(), new_token().unwrap());
        assert_eq!(a.len(), 32);
        assert!(a.bytes().all(|c| c.is_ascii_hexdigit()));
        assert_ne!(a, b);
    }
}
