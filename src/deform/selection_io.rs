//! Reading the vertex selections (`.sel`) and handle transforms (`.def`) of the deformation
//! benchmark of Botsch and Sorkine ("On Linear Variational Surface Deformation Methods", 2008),
//! the format the ARAP literature's test cases (the cactus, the bar) come in.
//!
//! A `.sel` file lists one status per vertex, in the mesh's vertex order: `0` fixed, `1`
//! free (solved for), `2` handle; lines starting with `#` are comments. A `.def` file holds the
//! handle's 4×4 transformation, row by row (sixteen numbers after its comments). Both are
//! checked in full: a selection must cover exactly the mesh's vertices, and a transform must be
//! finite and affine (last row `0 0 0 1`).

use std::path::Path;

use glam::{DAffine3, DMat3, DVec3};

use super::io::MeshIoError;

/// What a selection file says of one vertex.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VertexRole {
    /// Held where it is (status `0`).
    Fixed,
    /// Free: moved by the solver (status `1`).
    Free,
    /// Part of the handle, moved by the `.def` transform (status `2`).
    Handle,
}

/// The role of every vertex of a mesh, as a `.sel` file gives them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VertexSelection {
    /// One role per vertex, in the mesh's vertex order.
    pub roles: Vec<VertexRole>,
}

fn parse_err(line: usize, message: impl Into<String>) -> MeshIoError {
    MeshIoError::Parse {
        line,
        message: message.into(),
    }
}

/// Lines of `text` with their 1-based numbers, comments (`#` to the end of the line) and blank
/// lines left out.
fn content_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.split('#').next().unwrap_or("").trim()))
        .filter(|(_, l)| !l.is_empty())
}

fn read_text(path: &Path) -> Result<String, MeshIoError> {
    std::fs::read_to_string(path).map_err(|source| MeshIoError::Io {
        path: path.display().to_string(),
        source,
    })
}

impl VertexSelection {
    /// Parses a `.sel` file for a mesh of `vertex_count` vertices. Every status must be `0`, `1`
    /// or `2` (several per line are accepted), and there must be exactly one per vertex.
    pub fn parse_sel(text: &str, vertex_count: usize) -> Result<Self, MeshIoError> {
        let mut roles = Vec::with_capacity(vertex_count.min(text.len() / 2 + 1));
        for (line, content) in content_lines(text) {
            for token in content.split_whitespace() {
                let role = match token {
                    "0" => VertexRole::Fixed,
                    "1" => VertexRole::Free,
                    "2" => VertexRole::Handle,
                    other => {
                        return Err(parse_err(
                            line,
                            format!("expected a vertex status 0, 1 or 2, found {other:?}"),
                        ));
                    }
                };
                if roles.len() == vertex_count {
                    return Err(parse_err(
                        line,
                        format!("more statuses than the mesh's {vertex_count} vertices"),
                    ));
                }
                roles.push(role);
            }
        }
        if roles.len() != vertex_count {
            return Err(parse_err(
                text.lines().count().max(1),
                format!(
                    "{} statuses for a mesh of {vertex_count} vertices",
                    roles.len()
                ),
            ));
        }
        Ok(Self { roles })
    }

    /// Reads a `.sel` file for a mesh of `vertex_count` vertices.
    pub fn read(path: impl AsRef<Path>, vertex_count: usize) -> Result<Self, MeshIoError> {
        Self::parse_sel(&read_text(path.as_ref())?, vertex_count)
    }

    /// The vertices with `role`, in increasing order.
    pub fn vertices(&self, role: VertexRole) -> Vec<u32> {
        self.roles
            .iter()
            .enumerate()
            .filter(|(_, r)| **r == role)
            .map(|(v, _)| v as u32)
            .collect()
    }
}

/// Parses a `.def` file: the handle's 4×4 transformation, row by row. The last row must be
/// `0 0 0 1` (within 1e-6) and every entry finite.
pub fn parse_handle_transform(text: &str) -> Result<DAffine3, MeshIoError> {
    let mut values = Vec::with_capacity(16);
    let mut last_line = 1;
    for (line, content) in content_lines(text) {
        last_line = line;
        for token in content.split_whitespace() {
            let v: f64 = token
                .parse()
                .map_err(|_| parse_err(line, format!("bad matrix entry {token:?}")))?;
            if !v.is_finite() {
                return Err(parse_err(line, "non-finite matrix entry"));
            }
            if values.len() == 16 {
                return Err(parse_err(line, "more than 16 matrix entries"));
            }
            values.push(v);
        }
    }
    if values.len() != 16 {
        return Err(parse_err(
            last_line,
            format!("{} matrix entries, expected 16 (4 rows of 4)", values.len()),
        ));
    }
    let row = |r: usize| &values[4 * r..4 * r + 4];
    let bottom = row(3);
    if bottom[0].abs() > 1e-6
        || bottom[1].abs() > 1e-6
        || bottom[2].abs() > 1e-6
        || (bottom[3] - 1.0).abs() > 1e-6
    {
        return Err(parse_err(
            last_line,
            format!("the last row {bottom:?} is not 0 0 0 1: not an affine transform"),
        ));
    }
    let column = |c: usize| DVec3::new(row(0)[c], row(1)[c], row(2)[c]);
    Ok(DAffine3 {
        matrix3: DMat3::from_cols(column(0), column(1), column(2)),
        translation: column(3),
    })
}

/// Reads a `.def` file (see [`parse_handle_transform`]).
pub fn read_handle_transform(path: impl AsRef<Path>) -> Result<DAffine3, MeshIoError> {
    parse_handle_transform(&read_text(path.as_ref())?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn selection_reads_statuses_and_checks_the_count() {
        let sel = VertexSelection::parse_sel("# 4 vertices\n0\n1\n2 1\n", 4).unwrap();
        assert_eq!(sel.vertices(VertexRole::Fixed), vec![0]);
        assert_eq!(sel.vertices(VertexRole::Free), vec![1, 3]);
        assert_eq!(sel.vertices(VertexRole::Handle), vec![2]);
        assert!(VertexSelection::parse_sel("0\n1\n", 3).is_err());
        assert!(VertexSelection::parse_sel("0\n1\n2\n", 2).is_err());
        let bad = VertexSelection::parse_sel("0\n3\n", 2).unwrap_err();
        assert!(matches!(bad, MeshIoError::Parse { line: 2, .. }), "{bad}");
    }

    #[test]
    fn handle_transform_is_read_row_by_row() {
        let t = parse_handle_transform("# m\n1 0 0 5\n0 0 -1 6\n0 1 0 7\n0 0 0 1\n").unwrap();
        assert_eq!(t.translation, DVec3::new(5.0, 6.0, 7.0));
        // Row 1 says y' = -z: the point (0, 0, 1) goes to (5, 5, 7).
        assert_eq!(
            t.transform_point3(DVec3::Z),
            DVec3::new(5.0, 5.0, 7.0),
            "rows read as columns"
        );
        assert!(parse_handle_transform("1 0 0 0\n0 1 0 0\n0 0 1 0\n1 0 0 1\n").is_err());
        assert!(parse_handle_transform("1 0 0 0\n0 1 0 0\n0 0 1 0\n").is_err());
        assert!(parse_handle_transform("1 0 0 0\n0 1 0 0\n0 0 1 NaN\n0 0 0 1\n").is_err());
    }
}
