//! A glTF file's document and buffers, and the bounds every reader of the crate applies to what
//! a file claims. A file may claim any element count for an accessor: a sparse accessor with no
//! buffer view reads as `count` zeros, so a few bytes can ask for billions of elements. Every
//! accessor a reader collects goes through `GltfFile::admit`, which checks its type and layout
//! against what the reader reads and refuses one past
//! [`MAX_ACCESSOR_ELEMENTS`] and a file whose reads together pass [`MAX_FILE_ELEMENTS`].

use std::cell::Cell;
use std::path::Path;

/// The most elements (vertices, keys, matrices) one accessor may hold: 16.7 million, above any
/// character's vertex count or a clip channel's key count.
pub const MAX_ACCESSOR_ELEMENTS: usize = 1 << 24;

/// The most elements all the accessors one read of a file may hold together: 33.5 million
/// (e.g. a 100-joint clip of 55 000 keys with a separate time track per channel), about 1 GB
/// once converted to double precision.
pub const MAX_FILE_ELEMENTS: usize = 1 << 25;

/// A glTF file could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GltfFileError {
    /// The bytes are not a glTF (JSON) or GLB file the `gltf` crate accepts.
    #[error("not a readable glTF file: {0}")]
    Parse(String),
    /// A buffer names the GLB binary chunk, and there is none.
    #[error("the GLB binary chunk is missing")]
    MissingBinChunk,
    /// A buffer is a `data:` URI (not read: save the file as `.glb`).
    #[error("data: URIs are not read; save the file as .glb")]
    DataUri,
    /// The file, or one of its external buffers, could not be read.
    #[error("cannot read {path}: {message}")]
    Io {
        /// Where it was looked for.
        path: String,
        /// The file system's message.
        message: String,
    },
    /// An accessor is not what its use asks for (its type, its component type, its stride or
    /// its sparse part).
    #[error("accessor {accessor} cannot be read as {element:?}: {problem}")]
    Accessor {
        /// The accessor's index.
        accessor: usize,
        /// What it was to be read as.
        element: AccessorUse,
        /// What is wrong.
        problem: String,
    },
    /// An accessor claims more elements than [`MAX_ACCESSOR_ELEMENTS`].
    #[error("accessor {accessor} claims {count} elements, past the bound of {limit}")]
    AccessorTooLarge {
        /// The accessor's index.
        accessor: usize,
        /// The count it claims.
        count: usize,
        /// [`MAX_ACCESSOR_ELEMENTS`].
        limit: usize,
    },
    /// The accessors read from the file hold more than [`MAX_FILE_ELEMENTS`] together.
    #[error("the file's accessors hold more than {limit} elements together")]
    FileTooLarge {
        /// [`MAX_FILE_ELEMENTS`].
        limit: usize,
    },
    /// An accessor the reader needs has no data in the buffers (a view past a buffer's end,
    /// a wrong type).
    #[error("{what} cannot be read (its accessor has no data in the file's buffers)")]
    Unreadable {
        /// What was being read.
        what: String,
    },
}

/// The JSON of a `.gltf` (the bytes themselves) or of a `.glb` (its JSON chunk). A GLB header
/// whose total length is shorter than the header itself is refused here: `gltf` 1.4 subtracts
/// the header size from it unchecked (a panic where overflow is checked, as in debug builds).
pub(crate) fn json_of(bytes: &[u8]) -> Result<std::borrow::Cow<'_, [u8]>, GltfFileError> {
    if !bytes.starts_with(b"glTF") {
        return Ok(std::borrow::Cow::Borrowed(bytes));
    }
    check_glb_header(bytes)?;
    gltf::Glb::from_slice(bytes)
        .map(|glb| glb.json)
        .map_err(|e| GltfFileError::Parse(e.to_string()))
}

/// Refuses a GLB whose header gives a total length shorter than the header (see [`json_of`]).
fn check_glb_header(bytes: &[u8]) -> Result<(), GltfFileError> {
    if !bytes.starts_with(b"glTF") {
        return Ok(());
    }
    const HEADER: usize = 12;
    let length = bytes
        .get(8..12)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    if length.is_none_or(|l| l < HEADER) {
        return Err(GltfFileError::Parse(format!(
            "the GLB header gives a total length of {} bytes, less than its own {HEADER}",
            length.unwrap_or(0)
        )));
    }
    Ok(())
}

/// Refuses a file whose mesh primitive names a `POSITION` accessor that does not exist:
/// `gltf-json` 1.4's validation indexes the accessor list with it unchecked (and panics) before
/// it reports the index as invalid. Everything else is left to the `gltf` crate's validation.
fn check_position_accessors(root: &gltf_json::Root) -> Result<(), GltfFileError> {
    let accessors = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position =
                gltf_json::validation::Checked::Valid(gltf_json::mesh::Semantic::Positions);
            if let Some(index) = primitive.attributes.get(&position)
                && index.value() >= accessors
            {
                return Err(GltfFileError::Parse(format!(
                    "mesh {m} primitive {p}: POSITION names accessor {}, and the file has {accessors}",
                    index.value()
                )));
            }
        }
    }
    Ok(())
}

/// Refuses an animation channel whose target node does not exist or whose path is not one
/// glTF defines: `gltf-json` 1.4 does not validate channel targets, and the `gltf` crate's
/// `Target::node` and `Target::property` unwrap them (a panic).
fn check_channel_targets(root: &gltf_json::Root) -> Result<(), GltfFileError> {
    for (a, animation) in root.animations.iter().enumerate() {
        for (c, channel) in animation.channels.iter().enumerate() {
            let node_ok = channel.target.node.value() < root.nodes.len();
            let path_ok = matches!(
                channel.target.path,
                gltf_json::validation::Checked::Valid(_)
            );
            if !(node_ok && path_ok) {
                return Err(GltfFileError::Parse(format!(
                    "animation {a} channel {c} targets a node or a path that does not exist"
                )));
            }
        }
    }
    Ok(())
}

/// A parsed glTF file and its buffers, with the element budget of one read.
pub struct GltfFile {
    /// The document (and, for a GLB, its binary chunk).
    pub(crate) gltf: gltf::Gltf,
    /// The file's buffers, indexed like the document's.
    pub(crate) buffers: Vec<Vec<u8>>,
    elements: Cell<usize>,
}

impl GltfFile {
    /// Parses `bytes` (a `.gltf` or `.glb`) and reads its buffers: the GLB binary chunk, or
    /// files next to a `.gltf` in `folder` (the working directory when `None`).
    pub fn parse(bytes: &[u8], folder: Option<&Path>) -> Result<Self, GltfFileError> {
        // Parsed once, checked for what the gltf crates would panic on, then validated.
        let parse = |e: gltf::Error| GltfFileError::Parse(e.to_string());
        check_glb_header(bytes)?;
        let unchecked = gltf::Gltf::from_slice_without_validation(bytes).map_err(parse)?;
        let root = unchecked.document.into_json();
        check_position_accessors(&root)?;
        check_channel_targets(&root)?;
        let gltf = gltf::Gltf {
            document: gltf::Document::from_json(root).map_err(parse)?,
            blob: unchecked.blob,
        };
        let buffers = gltf
            .document
            .buffers()
            .map(|buffer| match buffer.source() {
                gltf::buffer::Source::Bin => {
                    gltf.blob.clone().ok_or(GltfFileError::MissingBinChunk)
                }
                gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                    Err(GltfFileError::DataUri)
                }
                gltf::buffer::Source::Uri(uri) => {
                    let path = folder.unwrap_or(Path::new(".")).join(uri);
                    std::fs::read(&path).map_err(|e| GltfFileError::Io {
                        path: path.display().to_string(),
                        message: e.to_string(),
                    })
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            gltf,
            buffers,
            elements: Cell::new(0),
        })
    }

    /// Reads the file at `path` (its external buffers from the same folder) and parses it.
    pub fn read(path: &Path) -> Result<Self, GltfFileError> {
        let bytes = std::fs::read(path).map_err(|e| GltfFileError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        Self::parse(&bytes, path.parent())
    }

    /// The document.
    pub fn document(&self) -> &gltf::Document {
        &self.gltf.document
    }

    /// The bytes of buffer `buffer`, for the `gltf` crate's readers.
    pub(crate) fn buffer(&self, buffer: gltf::Buffer<'_>) -> Option<&[u8]> {
        self.buffers.get(buffer.index()).map(Vec::as_slice)
    }

    /// Admits `accessor` before a reader of the `gltf` crate collects it as `element`: refuses
    /// one of another type or component type than the reader reads, with a stride shorter
    /// than its element or no elements (the reader would read past its items, or panic where
    /// it asserts), one that claims more than [`MAX_ACCESSOR_ELEMENTS`], and one that would
    /// bring this file's reads past [`MAX_FILE_ELEMENTS`].
    pub(crate) fn admit(
        &self,
        accessor: &gltf::Accessor<'_>,
        element: AccessorUse,
    ) -> Result<(), GltfFileError> {
        let index = accessor.index();
        let mismatch = |what: String| GltfFileError::Accessor {
            accessor: index,
            element,
            problem: what,
        };
        use gltf::accessor::{DataType as D, Dimensions as N};
        let (dimensions, types): (N, &[D]) = match element {
            AccessorUse::Positions | AccessorUse::Vectors => (N::Vec3, &[D::F32]),
            AccessorUse::Joints => (N::Vec4, &[D::U8, D::U16]),
            AccessorUse::Weights => (N::Vec4, &[D::F32, D::U8, D::U16]),
            AccessorUse::Indices => (N::Scalar, &[D::U8, D::U16, D::U32]),
            AccessorUse::Matrices => (N::Mat4, &[D::F32]),
            AccessorUse::Times => (N::Scalar, &[D::F32]),
            AccessorUse::Rotations => (N::Vec4, &[D::F32, D::I8, D::U8, D::I16, D::U16]),
        };
        if accessor.dimensions() != dimensions || !types.contains(&accessor.data_type()) {
            return Err(mismatch(format!(
                "it holds {:?} of {:?}",
                accessor.dimensions(),
                accessor.data_type()
            )));
        }
        let size = accessor.size();
        if accessor.count() == 0 {
            return Err(mismatch("it has no elements".into()));
        }
        if let Some(stride) = accessor.view().and_then(|v| v.stride())
            && stride < size
        {
            return Err(mismatch(format!(
                "its stride {stride} is shorter than its {size}-byte elements"
            )));
        }
        if let Some(sparse) = accessor.sparse() {
            let index_size = sparse.indices().index_type().size();
            let short = |stride: Option<usize>, needed: usize| stride.is_some_and(|s| s < needed);
            if sparse.count() == 0
                || sparse.count() > accessor.count()
                || short(sparse.indices().view().stride(), index_size)
                || short(sparse.values().view().stride(), size)
            {
                return Err(mismatch("its sparse part has no elements, more than the accessor, or a stride shorter than its elements".into()));
            }
        }
        let count = accessor.count();
        if count > MAX_ACCESSOR_ELEMENTS {
            return Err(GltfFileError::AccessorTooLarge {
                accessor: index,
                count,
                limit: MAX_ACCESSOR_ELEMENTS,
            });
        }
        let total = self.elements.get() + count;
        if total > MAX_FILE_ELEMENTS {
            return Err(GltfFileError::FileTooLarge {
                limit: MAX_FILE_ELEMENTS,
            });
        }
        self.elements.set(total);
        Ok(())
    }
}

/// What a reader collects an accessor as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AccessorUse {
    /// Vertex positions (`VEC3` of `f32`).
    Positions,
    /// Joint indices (`VEC4` of `u8` or `u16`).
    Joints,
    /// Joint weights (`VEC4` of `f32`, or normalised `u8`/`u16`).
    Weights,
    /// Triangle indices (`SCALAR` of `u8`, `u16` or `u32`).
    Indices,
    /// Inverse bind matrices (`MAT4` of `f32`).
    Matrices,
    /// Key times (`SCALAR` of `f32`).
    Times,
    /// Translations or scales of a clip (`VEC3` of `f32`).
    Vectors,
    /// Rotations of a clip (`VEC4` of `f32` or a normalised integer type).
    Rotations,
}
