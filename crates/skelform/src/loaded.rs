//! A scene as a front end holds it: the checked description, and what is needed to build it
//! again in another pose.

use std::ops::Deref;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use skelform_scene::{LoadOptions, SceneError};

use crate::Error;

/// A checked scene, ready to mesh.
///
/// It dereferences to the scene description ([`skelform_scene::Scene`]: domain, method,
/// field, skeleton, output settings) and keeps the source text, so that
/// [`Overrides::pose`](crate::Overrides::pose) can rebuild the skeleton in another pose.
#[derive(Clone, Debug)]
pub struct Scene {
    description: Arc<skelform_scene::Scene>,
    text: Arc<str>,
    /// The folder relative paths in the file are taken from (the file's folder).
    base: Option<PathBuf>,
    /// The pose the description was built in, when one was asked for.
    pose: Option<String>,
}

impl Scene {
    /// Reads and checks a scene file; errors name the file, line and column.
    pub fn load(path: impl AsRef<Path>) -> Result<Scene, Error> {
        Scene::load_with(path, &LoadOptions::default())
    }

    /// Reads and checks a scene file, with choices the file leaves open (a pose).
    pub fn load_with(path: impl AsRef<Path>, options: &LoadOptions) -> Result<Scene, Error> {
        let path = path.as_ref();
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|source| SceneError::Io { path: shown.clone(), source })?;
        let base = path.parent().map(Path::to_path_buf);
        Scene::build(text.into(), &shown, base, options.pose.clone())
    }

    /// Checks scene text; `origin` names it in messages (a file name, or `"<string>"`).
    /// Relative output paths in the text are left as they are.
    pub fn parse(text: &str, origin: &str) -> Result<Scene, Error> {
        Scene::build(text.into(), origin, None, None)
    }

    fn build(
        text: Arc<str>,
        origin: &str,
        base: Option<PathBuf>,
        pose: Option<String>,
    ) -> Result<Scene, Error> {
        let options = LoadOptions { pose: pose.clone() };
        let mut description = skelform_scene::Scene::parse_with(&text, origin, &options)?;
        if let (Some(file), Some(dir)) = (&description.output.file, &base) {
            description.output.file = Some(dir.join(file));
        }
        Ok(Scene { description: Arc::new(description), text, base, pose })
    }

    /// The same scene with its skeleton in the named pose (this one, shared, when it is
    /// already in that pose).
    pub fn posed(&self, pose: &str) -> Result<Scene, Error> {
        let current = self
            .description
            .articulation
            .as_ref()
            .map(|a| a.pose.as_str())
            .or(self.pose.as_deref());
        if current == Some(pose) {
            return Ok(self.clone());
        }
        Scene::build(
            self.text.clone(),
            &self.description.origin,
            self.base.clone(),
            Some(pose.to_string()),
        )
    }

    /// The checked description.
    pub fn description(&self) -> &skelform_scene::Scene {
        &self.description
    }

    /// The text the scene was read from.
    pub fn text(&self) -> &str {
        &self.text
    }
}

impl Deref for Scene {
    type Target = skelform_scene::Scene;
    fn deref(&self) -> &skelform_scene::Scene {
        &self.description
    }
}
