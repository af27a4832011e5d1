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
    /// Why the scene's `[output] file` may not be written, when it may not.
    output_refused: Option<String>,
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
        Scene::build(text.into(), &shown, base, options.clone())
    }

    /// Checks scene text; `origin` names it in messages (a file name, or `"<string>"`).
    /// Relative output paths in the text are left as they are.
    pub fn parse(text: &str, origin: &str) -> Result<Scene, Error> {
        Scene::build(text.into(), origin, None, LoadOptions::default())
    }

    /// Checks scene text whose relative paths (a sweep's `section_image`) are taken from the
    /// folder `base`: an editor's scene, held as text but belonging to a file there.
    pub fn parse_in(text: &str, origin: &str, base: &Path) -> Result<Scene, Error> {
        Scene::build(text.into(), origin, Some(base.to_path_buf()), LoadOptions::default())
    }

    /// A scene of one field over `domain`, with every other setting at its default (the
    /// grid method, 128 samples along the longest side): for front ends whose field is not
    /// written in the scene language (a Python function, a field built in Rust). `origin`
    /// names it in messages. The domain is checked as a scene file's is.
    pub fn from_field(
        field: Arc<dyn skelform_field::Field>,
        domain: skelform_field::Aabb,
        origin: &str,
    ) -> Result<Scene, Error> {
        let (lo, hi) = (domain.min, domain.max);
        // Written out and checked like any scene's domain, so that the limits and messages
        // are the same; the formula is a placeholder that the field then replaces.
        let text = format!(
            "[domain]\nmin = [{:?}, {:?}, {:?}]\nmax = [{:?}, {:?}, {:?}]\n[field]\nformula = \"0\"\n",
            lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
        );
        let mut scene = Scene::build(text.into(), origin, None, LoadOptions::default())?;
        Arc::make_mut(&mut scene.description).field = field;
        Ok(scene)
    }

    fn build(
        text: Arc<str>,
        origin: &str,
        base: Option<PathBuf>,
        options: LoadOptions,
    ) -> Result<Scene, Error> {
        let pose = options.pose.clone();
        let options = LoadOptions { base: options.base.or_else(|| base.clone()), ..options };
        let mut description = skelform_scene::Scene::parse_with(&text, origin, &options)?;
        let output_refused = description.output.file.as_deref().and_then(outside_folder);
        if let (Some(file), Some(dir)) = (&description.output.file, &base) {
            description.output.file = Some(dir.join(file));
        }
        Ok(Scene { description: Arc::new(description), text, base, pose, output_refused })
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
        let options = LoadOptions { pose: Some(pose.to_string()), ..LoadOptions::default() };
        Scene::build(self.text.clone(), &self.description.origin, self.base.clone(), options)
    }

    /// The same scene with its skeleton a fraction `t` (0 to 1) of the way from pose `from`
    /// to pose `to`: each joint's rotation interpolated (spherically), as the dissertation
    /// animates an articulated skeleton (§2.8), so limbs keep their lengths.
    pub fn posed_between(&self, from: &str, to: &str, t: f64) -> Result<Scene, Error> {
        let options = LoadOptions {
            pose: Some(from.to_string()),
            toward: Some(skelform_scene::PoseBlend { pose: to.to_string(), t }),
            ..LoadOptions::default()
        };
        Scene::build(self.text.clone(), &self.description.origin, self.base.clone(), options)
    }

    /// Where the scene asks its mesh to be written (`[output] file`, relative to the scene's
    /// folder), or `None` when it does not say. A scene may name a file in its own folder or
    /// below it only: a scene from elsewhere must not replace files it points at with `..`
    /// or an absolute path (only the command line, or the caller, may name those).
    pub fn output_file(&self) -> Result<Option<&Path>, Error> {
        match &self.output_refused {
            Some(why) => Err(Error::Invalid {
                origin: self.description.origin.clone(),
                message: why.clone(),
            }),
            None => Ok(self.description.output.file.as_deref()),
        }
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

/// Why a scene's own output path leaves the scene's folder, if it does.
fn outside_folder(file: &Path) -> Option<String> {
    use std::path::Component;
    let escapes = file.components().any(|c| !matches!(c, Component::Normal(_) | Component::CurDir));
    escapes.then(|| {
        format!(
            "[output] file = \"{}\" is outside the scene's folder; a scene may only name a file \
             in its folder or below it (give the path on the command line with -o to write there)",
            file.display()
        )
    })
}
