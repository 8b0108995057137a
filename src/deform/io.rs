//! Reading OFF and OBJ triangle meshes (for tools, tests and benchmarks).

use std::path::Path;

use glam::DVec3;

/// A plain triangle mesh.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriMesh {
    /// Vertex positions.
    pub positions: Vec<DVec3>,
    /// Triangles (0-based indices). Polygons are fan-triangulated on load.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Corners `(lo, hi)` of the mesh's axis-aligned bounding box (`lo > hi` when empty).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        bounding_box(&self.positions)
    }
}

/// Corners `(lo, hi)` of the axis-aligned bounding box of `points` (`lo > hi` when empty).
pub fn bounding_box(points: &[DVec3]) -> (DVec3, DVec3) {
    points.iter().fold(
        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    )
}

/// Mean of `points[v]` over the listed vertices that exist (zero when none do): the pivot of a
/// handle, the centre of a region.
pub fn centroid(points: &[DVec3], vertices: &[u32]) -> DVec3 {
    let (sum, n) = vertices
        .iter()
        .filter_map(|&v| points.get(v as usize))
        .fold((DVec3::ZERO, 0usize), |(sum, n), p| (sum + *p, n + 1));
    if n == 0 { DVec3::ZERO } else { sum / n as f64 }
}

/// A mesh file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum MeshIoError {
    /// File system error.
    #[error("cannot read {path}: {source}")]
    Io {
        /// Path.
        path: String,
        /// Cause.
        source: std::io::Error,
    },
    /// The content is malformed.
    #[error("line {line}: {message}")]
    Parse {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Unknown extension.
    #[error("unsupported mesh format {0:?} (expected .off or .obj)")]
    UnsupportedFormat(String),
}

fn parse_err(line: usize, message: impl Into<String>) -> MeshIoError {
    MeshIoError::Parse {
        line,
        message: message.into(),
    }
}

impl TriMesh {
    /// Reads an `.off` or `.obj` file, chosen by extension.
    pub fn read(path: impl AsRef<Path>) -> Result<Self, MeshIoError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| MeshIoError::Io {
            path: path.display().to_string(),
            source,
        })?;
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .as_deref()
        {
            Some("off") => Self::parse_off(&text),
            Some("obj") => Self::parse_obj(&text),
            other => Err(MeshIoError::UnsupportedFormat(
                other.unwrap_or_default().to_string(),
            )),
        }
    }

    /// Parses ASCII OFF and its variants (`COFF`, `NOFF`, `CNOFF`, …): one vertex or face
    /// per line; extra per-vertex values (normals, colours) and per-face colours are ignored.
    pub fn parse_off(text: &str) -> Result<Self, MeshIoError> {
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(ln, l)| (ln + 1, l.split('#').next().unwrap_or("").trim()))
            .filter(|(_, l)| !l.is_empty());
        let (ln, head) = lines.next().ok_or_else(|| parse_err(1, "empty file"))?;
        let mut head_tokens = head.split_whitespace();
        let keyword = head_tokens.next().unwrap_or("");
        let counts_line: Vec<&str> = if keyword.ends_with("OFF") && keyword.len() <= 6 {
            let rest: Vec<&str> = head_tokens.collect();
            if rest.is_empty() {
                let (_, l) = lines
                    .next()
                    .ok_or_else(|| parse_err(ln, "missing vertex/face counts"))?;
                l.split_whitespace().collect()
            } else {
                rest
            }
        } else {
            return Err(parse_err(
                ln,
                format!("expected OFF header, found {keyword:?}"),
            ));
        };
        let count = |i: usize, what: &str| -> Result<usize, MeshIoError> {
            let t = counts_line
                .get(i)
                .ok_or_else(|| parse_err(ln + 1, format!("missing {what}")))?;
            t.parse()
                .map_err(|_| parse_err(ln + 1, format!("expected {what}, found {t:?}")))
        };
        let nv = count(0, "vertex count")?;
        let nf = count(1, "face count")?;
        if nv > 100_000_000 || nf > 200_000_000 {
            return Err(parse_err(ln, "vertex/face counts are implausibly large"));
        }
        // Reserve no more than the text can hold (a vertex line takes at least 6 bytes, a face
        // line 7): a header may claim any count.
        let mut positions = Vec::with_capacity(nv.min(text.len() / 6));
        for k in 0..nv {
            let (ln, l) = lines
                .next()
                .ok_or_else(|| parse_err(0, format!("file ends after {k} of {nv} vertices")))?;
            let mut c = [0.0f64; 3];
            let mut it = l.split_whitespace();
            for v in &mut c {
                let t = it
                    .next()
                    .ok_or_else(|| parse_err(ln, "vertex needs 3 coordinates"))?;
                *v = t
                    .parse::<f64>()
                    .map_err(|_| parse_err(ln, format!("bad coordinate {t:?}")))?;
                if !v.is_finite() {
                    return Err(parse_err(ln, "non-finite coordinate"));
                }
            }
            positions.push(DVec3::from_array(c));
        }
        let mut triangles = Vec::with_capacity(nf.min(text.len() / 7));
        for f in 0..nf {
            let (ln, l) = lines
                .next()
                .ok_or_else(|| parse_err(0, format!("file ends after {f} of {nf} faces")))?;
            let mut it = l.split_whitespace();
            let t = it.next().unwrap_or("");
            let k: usize = t
                .parse()
                .map_err(|_| parse_err(ln, format!("expected face size, found {t:?}")))?;
            if !(3..=1024).contains(&k) {
                return Err(parse_err(ln, format!("face with {k} corners")));
            }
            let mut idx = Vec::with_capacity(k);
            for _ in 0..k {
                let t = it
                    .next()
                    .ok_or_else(|| parse_err(ln, "face has too few indices"))?;
                let i: usize = t
                    .parse()
                    .map_err(|_| parse_err(ln, format!("bad face index {t:?}")))?;
                if i >= nv {
                    return Err(parse_err(
                        ln,
                        format!("face index {i} >= vertex count {nv}"),
                    ));
                }
                idx.push(i as u32);
            }
            for c in 1..k - 1 {
                triangles.push([idx[0], idx[c], idx[c + 1]]);
            }
        }
        Ok(Self {
            positions,
            triangles,
        })
    }

    /// Parses Wavefront OBJ `v` and `f` records (1-based or negative indices, `v/vt/vn`).
    pub fn parse_obj(text: &str) -> Result<Self, MeshIoError> {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for (ln, line) in text.lines().enumerate() {
            let ln = ln + 1;
            let mut it = line.split_whitespace();
            match it.next() {
                Some("v") => {
                    let mut c = [0.0f64; 3];
                    for v in &mut c {
                        let t = it
                            .next()
                            .ok_or_else(|| parse_err(ln, "vertex needs 3 coordinates"))?;
                        *v = t
                            .parse()
                            .map_err(|_| parse_err(ln, format!("bad coordinate {t:?}")))?;
                        if !v.is_finite() {
                            return Err(parse_err(ln, "non-finite coordinate"));
                        }
                    }
                    positions.push(DVec3::from_array(c));
                }
                Some("f") => {
                    let mut idx = Vec::new();
                    for t in it {
                        let first = t.split('/').next().unwrap_or("");
                        let i: i64 = first
                            .parse()
                            .map_err(|_| parse_err(ln, format!("bad face index {t:?}")))?;
                        let n = positions.len() as i64;
                        let i = if i > 0 { i - 1 } else { n + i };
                        if i < 0 || i >= n {
                            return Err(parse_err(ln, format!("face index {t} out of range")));
                        }
                        idx.push(i as u32);
                    }
                    if idx.len() < 3 {
                        return Err(parse_err(ln, "face with fewer than 3 corners"));
                    }
                    for c in 1..idx.len() - 1 {
                        triangles.push([idx[0], idx[c], idx[c + 1]]);
                    }
                }
                _ => {}
            }
        }
        if positions.is_empty() {
            return Err(parse_err(1, "no vertices"));
        }
        Ok(Self {
            positions,
            triangles,
        })
    }

    /// Writes Wavefront OBJ (`v` and `f` records).
    pub fn to_obj(&self) -> String {
        use std::fmt::Write;
        let mut s = String::with_capacity(self.positions.len() * 40);
        for p in &self.positions {
            let _ = writeln!(s, "v {:.6} {:.6} {:.6}", p.x, p.y, p.z);
        }
        for t in &self.triangles {
            let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        s
    }

    /// Writes ASCII OFF.
    pub fn to_off(&self) -> String {
        use std::fmt::Write;
        let mut s = format!("OFF\n{} {} 0\n", self.positions.len(), self.triangles.len());
        for p in &self.positions {
            let _ = writeln!(s, "{} {} {}", p.x, p.y, p.z);
        }
        for t in &self.triangles {
            let _ = writeln!(s, "3 {} {} {}", t[0], t[1], t[2]);
        }
        s
    }
}

/// Frames a glTF JSON document and its binary buffer as a binary glTF (`.glb`, glTF 2.0 §4.4):
/// the 12-byte header, a JSON chunk padded with spaces and a BIN chunk padded with zeros to
/// 4-byte boundaries.
pub fn glb_container(mut json: Vec<u8>, mut bin: Vec<u8>) -> Vec<u8> {
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut glb = Vec::with_capacity(total);
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(json.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&json);
    glb.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend_from_slice(&bin);
    glb
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_off_with_quads_and_comments() {
        let m =
            TriMesh::parse_off("OFF\n# c\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n").unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        let round = TriMesh::parse_off(&m.to_off()).unwrap();
        assert_eq!(round, m);
    }

    #[test]
    fn malformed_off_gives_line_numbers() {
        let e = TriMesh::parse_off("OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n").unwrap_err();
        assert!(matches!(e, MeshIoError::Parse { line: 4, .. }), "{e}");
        let e = TriMesh::parse_off("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n").unwrap_err();
        assert!(e.to_string().contains("face index 5"), "{e}");
        assert!(TriMesh::parse_off("OFF\n3 1 0\n0 0 0\n").is_err());
        assert!(TriMesh::parse_off("PLY\n").is_err());
        assert!(TriMesh::parse_off("").is_err());
        assert!(TriMesh::parse_off("OFF\n1 0 0\nnan 0 0\n").is_err());
        // COFF with colours, counts on the header line.
        let m = TriMesh::parse_off(
            "COFF 3 1 0\n0 0 0 1 2 3 4\n1 0 0 1 2 3 4\n0 1 0 1 2 3 4\n3 0 1 2 9 9 9\n",
        )
        .unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn parses_obj_with_slashes_and_negative_indices() {
        let m =
            TriMesh::parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1/1/1 2//1 -1\n").unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        assert!(TriMesh::parse_obj("v 0 0\n").is_err());
        assert!(TriMesh::parse_obj("v 0 0 0\nf 1 2 3\n").is_err());
        assert!(TriMesh::parse_obj("").is_err());
    }
}
