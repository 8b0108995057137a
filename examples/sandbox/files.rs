//! Saving and loading a setup (RON) and exporting the posed mesh (GLB); their test.

use super::*;

#[derive(serde::Serialize, serde::Deserialize)]
pub(super) struct Setup {
    pub(super) model: String,
    pub(super) selection: Vec<u8>,
    pub(super) handle_translation: [f32; 3],
    pub(super) handle_rotation: [f32; 4],
}

impl Setup {
    /// The saved handle pose.
    pub(super) fn pose(&self) -> Transform {
        Transform::from_translation(Vec3::from_array(self.handle_translation))
            .with_rotation(Quat::from_array(self.handle_rotation).normalize())
    }
}

pub(super) fn save_setup(sb: &Sandbox, handle: Transform) -> Result<(), String> {
    let s = Setup {
        model: sb.model_name.clone(),
        selection: sb.selection.clone(),
        handle_translation: handle.translation.to_array(),
        handle_rotation: handle.rotation.to_array(),
    };
    let text = ron::ser::to_string_pretty(&s, ron::ser::PrettyConfig::default())
        .map_err(|e| e.to_string())?;
    std::fs::write(&sb.setup_path, text).map_err(|e| e.to_string())
}

pub(super) fn load_setup(path: &str) -> Result<Setup, String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    ron::from_str(&text).map_err(|e| e.to_string())
}

/// Writes the posed mesh as a binary glTF (positions, normals, indices), validated by
/// re-reading it with the `gltf` crate before it is written.
pub(super) fn export_glb(mesh: &Mesh, path: &str) -> Result<(), String> {
    let Ok(VertexAttributeValues::Float32x3(pos)) = mesh.try_attribute(Mesh::ATTRIBUTE_POSITION)
    else {
        return Err("mesh has no positions".into());
    };
    let normals = match mesh.try_attribute(Mesh::ATTRIBUTE_NORMAL) {
        Ok(VertexAttributeValues::Float32x3(n)) => n.clone(),
        _ => vec![[0.0, 1.0, 0.0]; pos.len()],
    };
    let indices: Vec<u32> = mesh
        .try_indices()
        .map_err(|e| e.to_string())?
        .iter()
        .map(|i| i as u32)
        .collect();
    let mut bin = Vec::new();
    for p in pos {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let normals_offset = bin.len();
    for n in &normals {
        for c in n {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let indices_offset = bin.len();
    for i in &indices {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in pos {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let json = serde_json::json!({
        "asset": {"version": "2.0", "generator": "bevy_wii_deform sandbox"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "posed"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2}]}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": normals_offset, "target": 34962},
            {"buffer": 0, "byteOffset": normals_offset, "byteLength": indices_offset - normals_offset, "target": 34962},
            {"buffer": 0, "byteOffset": indices_offset, "byteLength": bin.len() - indices_offset, "target": 34963}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": pos.len(), "type": "VEC3", "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5126, "count": normals.len(), "type": "VEC3"},
            {"bufferView": 2, "componentType": 5125, "count": indices.len(), "type": "SCALAR"}
        ]
    });
    let json = serde_json::to_vec(&json).map_err(|e| e.to_string())?;
    let glb = bevy_wii_deform::deform::glb_container(json, bin);
    let (doc, buffers, _) = gltf::import_slice(&glb).map_err(|e| format!("invalid glTF: {e}"))?;
    let count = doc
        .meshes()
        .next()
        .and_then(|m| m.primitives().next())
        .map(|p| {
            p.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]))
                .read_positions()
                .map(|i| i.count())
                .unwrap_or(0)
        });
    if count != Some(pos.len()) {
        return Err("glTF round trip lost vertices".into());
    }
    std::fs::write(path, glb).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::ecs::world::CommandQueue;

    #[test]
    fn a_saved_setup_loads_back_with_its_selection_and_pose() {
        let mut sb = Sandbox::empty();
        sb.mesh = synth::bar(8, 10, 0.1, 1.0);
        let n = sb.mesh.positions.len();
        sb.selection = (0..n)
            .map(|i| match i {
                i if i < 8 => FIXED,
                i if i >= n - 10 => HANDLE,
                _ => FREE,
            })
            .collect();
        let path = std::env::temp_dir().join(format!("sandbox-setup-{}.ron", std::process::id()));
        sb.setup_path = path.display().to_string();
        let mut world = World::new();
        sb.mesh_entity = Some(world.spawn_empty().id());
        let pose = Transform::from_xyz(0.1, 0.9, 0.2).with_rotation(Quat::from_rotation_z(0.4));
        save_setup(&sb, pose).unwrap();
        let saved = std::mem::take(&mut sb.selection);
        let setup = load_setup(&sb.setup_path).unwrap();
        let _ = std::fs::remove_file(&path);
        assert_eq!(setup.selection, saved);
        // Restored as the panel does: the selection, and a new handle at the saved pose.
        sb.selection = setup.selection.clone();
        let mut queue = CommandQueue::default();
        let mut commands = Commands::new(&mut queue, &world);
        sync_regions(&mut commands, &mut sb, Some(setup.pose()));
        queue.apply(&mut world);
        let handle = sb.handle_entity.expect("a handle");
        let restored = world.get::<Transform>(handle).unwrap();
        assert!(
            restored.translation.distance(pose.translation) < 1e-6,
            "{restored:?}"
        );
        assert!(
            restored.rotation.angle_between(pose.rotation) < 1e-6,
            "{restored:?}"
        );
        let fixed = world.get::<FixedRegion>(sb.mesh_entity.unwrap()).unwrap();
        assert_eq!(fixed.0, (0..8).collect::<Vec<u32>>());
    }
}
