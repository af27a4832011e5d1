//! Mesh readers and writers: PLY, OBJ, STL and binary glTF.
//!
//! Writers to a path are atomic ([`atomic`], which every file skelform writes goes
//! through): the mesh is written into a temporary file in the target directory
//! (`.NAME.tmp-PID-N`), flushed and synced, then renamed over the target. On any error, and
//! on `SIGINT`/`SIGTERM`/`SIGHUP`, the temporary file is removed and the target is left as
//! it was. [`write_mesh`] also writes the files that go beside some meshes: a PLY's curves
//! file ([`PlyCurves::Separate`]) and an OBJ's material library.
//!
//! Readers take whole files written by other programs (see each module for what is
//! accepted) and never panic on malformed input: every error says where (the line for text,
//! the byte offset for binary data) and what was expected.

use std::fmt;
use std::fs;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::mesh::{Mesh, MeshError};

pub mod atomic;
pub mod gltf;
pub mod obj;
pub mod ply;
pub mod stl;
pub mod texture;

pub use gltf::{read_glb, write_glb};
pub use obj::{read_obj, write_obj, write_obj_with_mtl};
pub use ply::{read_ply, write_ply, write_ply_curves};
pub use stl::{read_stl, write_stl};
pub use texture::{decode_png, encode_png};

/// A mesh file format, chosen by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// Stanford PLY: binary little-endian (default) or ASCII; keeps normals, labels (with
    /// colours), curves (in a file beside it by default, see [`PlyCurves`]).
    Ply,
    /// Wavefront OBJ: text; keeps normals, labels (as groups, coloured by an `.mtl` beside
    /// it) and curves (as `l` lines).
    Obj,
    /// Binary STL: unlabelled triangle soup, welded on reading.
    Stl,
    /// Binary glTF 2.0: one primitive and material per region pair, normals, curves as
    /// lines; what Blender, MeshLab and web viewers open. Read without welding, node
    /// transforms applied.
    Glb,
}

impl Format {
    /// Every supported format.
    pub const ALL: [Format; 4] = [Format::Ply, Format::Obj, Format::Stl, Format::Glb];

    /// The format named by the extension of `path` (case-insensitive), if any.
    pub fn from_path(path: &Path) -> Option<Format> {
        Format::from_extension(path.extension()?.to_str()?)
    }

    /// The format of an extension without its dot (`"ply"`, `"OBJ"`...), if any.
    pub fn from_extension(ext: &str) -> Option<Format> {
        Format::ALL.into_iter().find(|f| f.extension().eq_ignore_ascii_case(ext))
    }

    /// The usual extension, lower case, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Ply => "ply",
            Format::Obj => "obj",
            Format::Stl => "stl",
            Format::Glb => "glb",
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Format::Ply => "PLY",
            Format::Obj => "OBJ",
            Format::Stl => "STL",
            Format::Glb => "glTF binary",
        })
    }
}

/// Where the PLY writer puts a mesh's curves.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum PlyCurves {
    /// In a file of their own beside the mesh, `OUT.curves.ply` for `OUT.ply` (see
    /// [`ply::curves_path`]): vertex and `edge` elements that trimesh and MeshLab read as a
    /// path, while the mesh file keeps only `vertex` and `face` elements, the layout every
    /// PLY reader accepts (meshio refuses any other element). The default. Writers to a
    /// stream ([`write_mesh_to`]) write the mesh part only; [`ply::write_ply_curves`] writes
    /// the other.
    #[default]
    Separate,
    /// In the mesh file, as an `edge` element `int vertex1, vertex2, region_a, region_b,
    /// region_c` after the faces: one self-contained file, which skelform reads but trimesh,
    /// meshio and pymeshlab refuse.
    Inline,
    /// Not written.
    None,
}

/// How to write a mesh. Build it from [`WriteOptions::default`] and change the fields you
/// need (`WriteOptions { ascii: true, ..WriteOptions::default() }`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WriteOptions {
    /// PLY only: write `format ascii 1.0` instead of binary little-endian.
    pub ascii: bool,
    /// Write per-vertex normals when the mesh has them (PLY, OBJ and glTF).
    pub normals: bool,
    /// Write the mesh's curves where the format has room for them (PLY as
    /// [`ply_curves`](Self::ply_curves) says, OBJ `l` lines, glTF line primitives); `false`
    /// leaves them out of every format (some readers, pymeshlab's glTF reader for one, fail
    /// on line primitives).
    pub curves: bool,
    /// PLY only: where the curves go (when [`curves`](Self::curves) is set).
    pub ply_curves: PlyCurves,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions { ascii: false, normals: true, curves: true, ply_curves: PlyCurves::Separate }
    }
}

impl WriteOptions {
    /// Where PLY curves go, once [`curves`](Self::curves) is taken into account.
    pub fn effective_ply_curves(&self) -> PlyCurves {
        if self.curves { self.ply_curves } else { PlyCurves::None }
    }
}

/// Bounds on what a file may expand to when read, checked before anything is allocated for
/// it, so that a small or lying file cannot make a reader claim gigabytes.
///
/// The absolute caps are what skelform's own PLY writer can index (`int` vertex indices),
/// far beyond any mesh the polygonizers make on one machine; a header declaring more is
/// refused at once rather than after reading. Text formats and PLY cannot expand beyond a
/// small constant per byte (every vertex and face takes bytes of the file, and the readers
/// reserve only what the bytes left can hold), so for them the caps are the only limit.
/// glTF can: accessors are shared by reference, and a 124 KB file whose 2000 primitives use
/// one index accessor describes 20 million triangles. Its reader therefore also counts every
/// vertex and index it reads (each primitive and each node instance anew) against
/// [`MAX_ELEMENTS_PER_BYTE`](limits::MAX_ELEMENTS_PER_BYTE) per byte of the file.
pub mod limits {
    /// The most vertices a mesh read from a file may have.
    pub const MAX_VERTICES: usize = i32::MAX as usize;
    /// The most triangles a mesh read from a file may have (after fan triangulation).
    pub const MAX_TRIANGLES: usize = i32::MAX as usize;
    /// glTF: the most vertices plus index entries read, per byte of the file (plus
    /// [`MIN_ELEMENTS`]). A file that stores each vertex and index once stays below one
    /// element per byte (a `u8` index is the smallest item); 16 leaves room for meshes
    /// instanced by several nodes and accessors shared by a few primitives.
    pub const MAX_ELEMENTS_PER_BYTE: u64 = 16;
    /// glTF: elements any file may expand to, whatever its size, so tiny files with a little
    /// sharing are never refused.
    pub const MIN_ELEMENTS: u64 = 1 << 16;
}

/// Why a mesh could not be read or written. The `Display` text is one line meant for users;
/// it already includes the cause, so print it with `{}` rather than walking `source()`.
///
/// `path` is `None` for the in-memory readers and writers (`read_ply` on a slice...); the
/// path-taking functions fill it in.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The file could not be opened or read.
    #[error("cannot read{}: {source}", name(.path))]
    Read {
        /// The file, or `None` for the in-memory readers.
        path: Option<PathBuf>,
        /// What the operating system said.
        source: io::Error,
    },
    /// The file (or its temporary file) could not be created, written, synced or renamed.
    #[error("cannot write{}: {source}", name(.path))]
    Write {
        /// The file to be written (not its temporary), or `None` for the in-memory writers.
        path: Option<PathBuf>,
        /// What the operating system said, from creating, writing, syncing or renaming.
        source: io::Error,
    },
    /// Malformed text (OBJ, ASCII PLY or STL, and every PLY header), with its 1-based line.
    #[error("{}line {line}: {msg}", prefix(.path))]
    Parse {
        /// The file, or `None` for the in-memory readers.
        path: Option<PathBuf>,
        /// 1-based line number of the malformed text.
        line: usize,
        /// What is wrong there, in words for users.
        msg: String,
    },
    /// Malformed binary data (binary PLY body, binary STL), with the byte offset in the file.
    #[error("{}byte {offset}: {msg}", prefix(.path))]
    Binary {
        /// The file, or `None` for the in-memory readers.
        path: Option<PathBuf>,
        /// Byte offset from the start of the file (header included) of the malformed data.
        offset: u64,
        /// What is wrong there, in words for users.
        msg: String,
    },
    /// The mesh handed to a writer breaks the [`Mesh`] invariants.
    #[error("cannot write{}: invalid mesh: {source}", name(.path))]
    InvalidMesh {
        /// The file to be written (not its temporary), or `None` for the in-memory writers.
        path: Option<PathBuf>,
        /// The invariant the mesh breaks.
        source: MeshError,
    },
    /// The mesh cannot be expressed in the format (too many triangles, too large an id...).
    #[error("cannot write{}: {msg}", name(.path))]
    Unsupported {
        /// The file to be written (not its temporary), or `None` for the in-memory writers.
        path: Option<PathBuf>,
        /// What the format cannot hold, in words for users.
        msg: String,
    },
    /// The extension names no supported format.
    #[error("{}: unknown mesh format: expected the extension .ply, .obj, .stl or .glb", .path.display())]
    UnknownFormat {
        /// The path whose extension was not recognised (extensions are compared without
        /// regard to case).
        path: PathBuf,
    },
}

fn name(path: &Option<PathBuf>) -> String {
    path.as_ref().map_or_else(String::new, |p| format!(" {}", p.display()))
}

fn prefix(path: &Option<PathBuf>) -> String {
    path.as_ref().map_or_else(String::new, |p| format!("{}: ", p.display()))
}

impl IoError {
    /// The file the error is about, where known.
    pub fn path(&self) -> Option<&Path> {
        match self {
            IoError::Read { path, .. }
            | IoError::Write { path, .. }
            | IoError::Parse { path, .. }
            | IoError::Binary { path, .. }
            | IoError::InvalidMesh { path, .. }
            | IoError::Unsupported { path, .. } => path.as_deref(),
            IoError::UnknownFormat { path } => Some(path),
        }
    }

    /// The same error naming `file`, unless it already names a file.
    pub fn with_path(mut self, file: &Path) -> Self {
        match &mut self {
            IoError::Read { path, .. }
            | IoError::Write { path, .. }
            | IoError::Parse { path, .. }
            | IoError::Binary { path, .. }
            | IoError::InvalidMesh { path, .. }
            | IoError::Unsupported { path, .. } => {
                if path.is_none() {
                    *path = Some(file.to_path_buf());
                }
            }
            IoError::UnknownFormat { .. } => {}
        }
        self
    }

    /// Whether the error is about the input's contents or name (malformed file, unknown
    /// extension) rather than a failure of the system (exit code 2 rather than 1).
    pub fn is_bad_input(&self) -> bool {
        matches!(
            self,
            IoError::Parse { .. } | IoError::Binary { .. } | IoError::UnknownFormat { .. }
        )
    }

    pub(crate) fn write(source: io::Error) -> Self {
        IoError::Write { path: None, source }
    }

    pub(crate) fn parse(line: usize, msg: impl Into<String>) -> Self {
        IoError::Parse { path: None, line, msg: msg.into() }
    }

    pub(crate) fn binary(offset: u64, msg: impl Into<String>) -> Self {
        IoError::Binary { path: None, offset, msg: msg.into() }
    }

    pub(crate) fn invalid(source: MeshError) -> Self {
        IoError::InvalidMesh { path: None, source }
    }

    pub(crate) fn unsupported(msg: impl Into<String>) -> Self {
        IoError::Unsupported { path: None, msg: msg.into() }
    }
}

/// Reads a mesh, choosing the reader by the extension of `path`.
pub fn read_mesh(path: &Path) -> Result<Mesh, IoError> {
    let format =
        Format::from_path(path).ok_or_else(|| IoError::UnknownFormat { path: path.into() })?;
    read_mesh_as(path, format)
}

/// Reads a mesh in the given format, whatever the extension of `path`. A PLY file without
/// curves takes them from `OUT.curves.ply` beside it when that file exists (see
/// [`PlyCurves::Separate`]); a curves file that does not match the mesh is an error.
pub fn read_mesh_as(path: &Path, format: Format) -> Result<Mesh, IoError> {
    let bytes =
        fs::read(path).map_err(|source| IoError::Read { path: Some(path.into()), source })?;
    let mut mesh = read_mesh_from(&bytes, format).map_err(|e| e.with_path(path))?;
    if format == Format::Ply && mesh.curves.is_empty() {
        let side = ply::curves_path(path);
        match fs::read(&side) {
            Ok(bytes) => {
                ply::attach_curves(&mut mesh, &bytes[..]).map_err(|e| e.with_path(&side))?
            }
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(source) => return Err(IoError::Read { path: Some(side), source }),
        }
    }
    Ok(mesh)
}

/// Reads a mesh in the given format from the whole contents of a file.
pub fn read_mesh_from(bytes: &[u8], format: Format) -> Result<Mesh, IoError> {
    match format {
        Format::Ply => read_ply(bytes),
        Format::Obj => read_obj(bytes),
        Format::Stl => read_stl(bytes),
        Format::Glb => read_glb(bytes),
    }
}

/// Writes `mesh` to `w` in `format`. `w` need not be buffered. Nothing is written for an
/// invalid mesh.
pub fn write_mesh_to(
    w: &mut impl Write,
    mesh: &Mesh,
    format: Format,
    opts: &WriteOptions,
) -> Result<(), IoError> {
    match format {
        Format::Ply => write_ply(w, mesh, opts),
        Format::Obj => write_obj(w, mesh, opts),
        Format::Stl => write_stl(w, mesh),
        Format::Glb => write_glb(w, mesh, opts),
    }
}

/// Writes `mesh` to `path` atomically: into a temporary file in the same directory, flushed
/// and synced, then renamed over `path`. On error the temporary file is removed and `path`
/// is untouched. The write-out to disk starts while the file is being written
/// ([`atomic::WriteAhead`]), so the sync waits only for what was written last.
///
/// Files beside the mesh, each written atomically too (before the mesh, so a mesh never
/// names a file that is not there):
/// - PLY with [`PlyCurves::Separate`] and curves: `OUT.curves.ply` ([`ply::curves_path`]).
///   Otherwise a curves file left there by an earlier run (one whose header says skelform
///   wrote it) is removed, so it is never read back as this mesh's curves.
/// - OBJ of a labelled mesh or one with curves: `OUT.mtl` ([`obj::mtl_path`]), the palette
///   colour of each region pair as a material, named by the `mtllib` line. A labelled mesh
///   with a texture and texture coordinates (the leaf's venation) also gets the image as
///   `OUT.texture.png` ([`obj::texture_path`]), every region's `map_Kd`.
pub fn write_mesh(
    path: &Path,
    mesh: &Mesh,
    format: Format,
    opts: &WriteOptions,
) -> Result<(), IoError> {
    mesh.validate().map_err(|e| IoError::invalid(e).with_path(path))?;
    let write = |path: &Path, f: &dyn Fn(&mut atomic::WriteAhead) -> Result<(), IoError>| {
        atomic::write_with(path, |file| f(&mut atomic::WriteAhead::new(file)))
            .map_err(|e| match e {
                atomic::AtomicError::Io(e) => IoError::write(e),
                atomic::AtomicError::Write(e) => e,
            })
            .map_err(|e| e.with_path(path))
    };
    match format {
        Format::Ply => {
            let side = ply::curves_path(path);
            if opts.effective_ply_curves() == PlyCurves::Separate && !mesh.curves.is_empty() {
                write(&side, &|file| write_ply_curves(file, mesh, opts))?;
                let written = write(path, &|file| write_mesh_to(file, mesh, format, opts));
                if written.is_err() {
                    // No curves file without its mesh.
                    let _ = fs::remove_file(&side);
                }
                return written;
            }
            if ply::is_our_curves_file(&side) {
                fs::remove_file(&side)
                    .map_err(|source| IoError::Write { path: Some(side.clone()), source })?;
            }
            write(path, &|file| write_mesh_to(file, mesh, format, opts))
        }
        Format::Obj if obj::wants_mtl(mesh, opts) => {
            let mtl = obj::mtl_path(path);
            let image = match &mesh.texture {
                Some(t) if !mesh.uvs.is_empty() && !mesh.labels.is_empty() => {
                    let png = texture::encode_png(t).map_err(|e| e.with_path(path))?;
                    let at = obj::texture_path(path);
                    write(&at, &|file| file.write_all(&png).map_err(IoError::write))?;
                    at.file_name().map(|n| n.to_string_lossy().into_owned())
                }
                _ => None,
            };
            write(&mtl, &|file| obj::write_mtl_with_texture(file, mesh, opts, image.as_deref()))?;
            let name = mtl.file_name().map(|n| n.to_string_lossy().into_owned());
            write(path, &|file| write_obj_with_mtl(file, mesh, opts, name.as_deref()))
        }
        _ => write(path, &|file| write_mesh_to(file, mesh, format, opts)),
    }
}

/// `path` with `.SUFFIX` put before its extension (`out.ply` → `out.curves.ply`), or added
/// when it has none.
pub(crate) fn beside(path: &Path, suffix: &str, ext: Option<&str>) -> PathBuf {
    let stem = path.file_stem().map(|s| s.to_os_string()).unwrap_or_default();
    let mut name = stem;
    if !suffix.is_empty() {
        name.push(".");
        name.push(suffix);
    }
    if let Some(e) = ext.map(std::ffi::OsStr::new).or_else(|| path.extension()) {
        name.push(".");
        name.push(e);
    }
    path.with_file_name(name)
}

/// A buffered writer over `w` for the format writers.
pub(crate) fn buffered<W: Write>(w: W) -> BufWriter<W> {
    BufWriter::with_capacity(1 << 16, w)
}

/// Flushes a buffered writer, turning the error into an [`IoError`].
pub(crate) fn finish<W: Write>(w: BufWriter<W>) -> Result<(), IoError> {
    let mut inner = w.into_inner().map_err(|e| IoError::write(e.into_error()))?;
    inner.flush().map_err(IoError::write)
}

/// Welds positions with identical coordinates (bit for bit, with `-0.0` taken as `0.0`)
/// into an indexed mesh. Shared by the STL reader and useful after reading triangle soups.
pub(crate) struct Welder {
    map: std::collections::HashMap<[u32; 3], u32>,
    pub(crate) positions: Vec<[f32; 3]>,
}

impl Welder {
    pub(crate) fn new() -> Self {
        Welder { map: std::collections::HashMap::new(), positions: Vec::new() }
    }

    pub(crate) fn index(&mut self, p: [f32; 3]) -> u32 {
        // Adding 0.0 turns -0.0 into 0.0 and leaves every other value alone.
        let p = p.map(|c| c + 0.0);
        let key = p.map(f32::to_bits);
        let next = self.positions.len() as u32;
        let positions = &mut self.positions;
        *self.map.entry(key).or_insert_with(|| {
            positions.push(p);
            next
        })
    }
}

/// Three numbers from the words of a text line (OBJ `v`/`vn`, STL `vertex`/`facet normal`),
/// with an error that says which is missing or malformed.
pub(crate) fn three_numbers<'a>(
    words: &mut impl Iterator<Item = &'a str>,
    line: usize,
    what: &str,
) -> Result<[f32; 3], IoError> {
    let mut out = [0.0; 3];
    for (k, c) in out.iter_mut().enumerate() {
        let word = words.next();
        *c = word.and_then(|w| w.parse().ok()).ok_or_else(|| {
            let msg = match word {
                Some(w) => {
                    format!("expected a number for {what} coordinate {}, found '{w}'", k + 1)
                }
                None => format!("expected 3 numbers after {what}, found {k}"),
            };
            IoError::parse(line, msg)
        })?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn format_from_path_is_case_insensitive() {
        assert_eq!(Format::from_path(Path::new("a/b.PLY")), Some(Format::Ply));
        assert_eq!(Format::from_path(Path::new("x.Obj")), Some(Format::Obj));
        assert_eq!(Format::from_path(Path::new("x.stl")), Some(Format::Stl));
        assert_eq!(Format::from_path(Path::new("x.GLB")), Some(Format::Glb));
        assert_eq!(Format::from_path(Path::new("x.gltf")), None);
        assert_eq!(Format::from_path(Path::new("ply")), None);
    }

    #[test]
    fn error_messages_name_the_file() {
        let e = IoError::parse(3, "expected a number").with_path(Path::new("m.obj"));
        assert_eq!(e.to_string(), "m.obj: line 3: expected a number");
        let e = IoError::parse(3, "expected a number");
        assert_eq!(e.to_string(), "line 3: expected a number");
        let e = IoError::binary(84, "truncated").with_path(Path::new("m.stl"));
        assert_eq!(e.to_string(), "m.stl: byte 84: truncated");
        assert!(e.is_bad_input());
        let e = IoError::write(io::Error::other("disk full")).with_path(Path::new("o.ply"));
        assert_eq!(e.to_string(), "cannot write o.ply: disk full");
        assert!(!e.is_bad_input());
        assert_eq!(e.path(), Some(Path::new("o.ply")));
    }
}
