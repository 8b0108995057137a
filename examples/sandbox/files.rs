//! Saving and loading a setup (RON: model, painted regions, handle pose) and exporting the
//! posed mesh (GLB).

use bevy::mesh::VertexAttributeValues;
use bevy::prelude::*;

use crate::history::{History, snapshot};
use crate::selection::{RegionsChanged, Selection};
use crate::{Model, SandboxSet, StatusLine};

/// Setup files and export, on [`FileCommand`]s.
pub struct FilesPlugin;

impl Plugin for FilesPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<FilePaths>()
            .add_message::<FileCommand>()
            .add_systems(Update, run_file_commands.in_set(SandboxSet::Edit));
    }
}

/// The paths typed in the panel.
#[derive(Resource)]
pub struct FilePaths {
    pub setup: String,
    pub export: String,
}

impl Default for FilePaths {
    fn default() -> Self {
        Self {
            setup: "sandbox_setup.ron".into(),
            export: "posed.glb".into(),
        }
    }
}

/// A file operation requested from the panel.
#[derive(Message, Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileCommand {
    /// Writes the model name, regions and handle pose to the setup path.
    SaveSetup,
    /// Restores regions and pose from the setup path (an undoable edit).
    LoadSetup,
    /// Writes the posed mesh to the export path.
    Export,
}

#[derive(serde::Serialize, serde::Deserialize)]
struct Setup {
    model: String,
    selection: Vec<u8>,
    handle_translation: [f32; 3],
    handle_rotation: [f32; 4],
}

impl Setup {
    /// The saved handle pose.
    fn pose(&self) -> Transform {
        Transform::from_translation(Vec3::from_array(self.handle_translation))
            .with_rotation(Quat::from_array(self.handle_rotation).normalize())
    }
}

fn run_file_commands(
    mut commands: MessageReader<FileCommand>,
    paths: Res<FilePaths>,
    model: Res<Model>,
    mut selection: ResMut<Selection>,
    (meshes, mesh3d, transforms): (Res<Assets<Mesh>>, Query<&Mesh3d>, Query<&Transform>),
    (mut history, mut status): (ResMut<History>, ResMut<StatusLine>),
    mut regions: MessageWriter<RegionsChanged>,
) {
    for command in commands.read() {
        let message = match command {
            FileCommand::SaveSetup => {
                let now = snapshot(&selection, &model, &transforms);
                save_setup(&paths.setup, &model.name, &now.selection, now.handle)
                    .map(|()| format!("saved {}", paths.setup))
            }
            FileCommand::LoadSetup => load_setup(&paths.setup).and_then(|setup| {
                if setup.model != model.name {
                    return Err(format!(
                        "setup is for model {:?}; load it first",
                        setup.model
                    ));
                }
                if setup.selection.len() != selection.labels.len() {
                    return Err("setup does not match this mesh".into());
                }
                history.checkpoint(snapshot(&selection, &model, &transforms));
                selection.labels = setup.selection.clone();
                regions.write(RegionsChanged {
                    pose: Some(setup.pose()),
                });
                Ok(format!("loaded {}", paths.setup))
            }),
            FileCommand::Export => model
                .entity
                .and_then(|e| mesh3d.get(e).ok())
                .and_then(|m| meshes.get(&m.0))
                .ok_or_else(|| "nothing to export".to_string())
                .and_then(|m| export_glb(m, &paths.export))
                .map(|()| format!("exported {}", paths.export)),
        };
        status.set(message.unwrap_or_else(|e| format!("{command:?} failed: {e}")));
    }
}

fn save_setup(path: &str, model: &str, selection: &[u8], handle: Transform) -> Result<(), String> {
    let s = Setup {
        model: model.into(),
        selection: selection.to_vec(),
        handle_translation: handle.translation.to_array(),
        handle_rotation: handle.rotation.to_array(),
    };
    let text = ron::ser::to_string_pretty(&s, ron::ser::PrettyConfig::default())
        .map_err(|e| e.to_string())?;
    std::fs::write(path, text).map_err(|e| e.to_string())
}

fn load_setup(path: &str) -> Result<Setup, String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    ron::from_str(&text).map_err(|e| e.to_string())
}

/// Writes the posed mesh as a binary glTF (positions, normals, indices), validated by
/// re-reading it with the `gltf` crate before it is written.
fn export_glb(mesh: &Mesh, path: &str) -> Result<(), String> {
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
    use crate::selection::{FIXED, FREE, HANDLE, apply_regions};
    use crate::{InputMethod, SandboxSet};
    use bevy::state::app::StatesPlugin;
    use bevy_wii_deform::deform::synth;
    use bevy_wii_deform::prelude::FixedRegion;

    /// Save → change everything → load, through the app's own systems and messages.
    #[test]
    fn a_saved_setup_loads_back_with_its_selection_and_pose() {
        let mut app = App::new();
        app.add_plugins((MinimalPlugins, StatesPlugin))
            .init_state::<InputMethod>()
            .init_resource::<Assets<Mesh>>()
            .init_resource::<Selection>()
            .init_resource::<History>()
            .init_resource::<StatusLine>()
            .add_message::<RegionsChanged>()
            .configure_sets(Update, (SandboxSet::Edit, SandboxSet::Regions).chain())
            .add_plugins(FilesPlugin)
            .add_systems(Update, apply_regions.in_set(SandboxSet::Regions));
        let path = std::env::temp_dir().join(format!("sandbox-setup-{}.ron", std::process::id()));
        app.world_mut().resource_mut::<FilePaths>().setup = path.display().to_string();
        let mesh = synth::bar(8, 10, 0.1, 1.0);
        let n = mesh.positions.len();
        let labels: Vec<u8> = (0..n)
            .map(|i| match i {
                i if i < 8 => FIXED,
                i if i >= n - 10 => HANDLE,
                _ => FREE,
            })
            .collect();
        let entity = app.world_mut().spawn(Transform::default()).id();
        app.insert_resource(Model {
            name: "bar".into(),
            mesh,
            diagonal: 1.0,
            entity: Some(entity),
            handle: None,
        });
        app.world_mut().resource_mut::<Selection>().labels = labels.clone();
        let pose = Transform::from_xyz(0.1, 0.9, 0.2).with_rotation(Quat::from_rotation_z(0.4));
        app.world_mut()
            .write_message(RegionsChanged { pose: Some(pose) });
        app.update();
        app.world_mut().write_message(FileCommand::SaveSetup);
        app.update();
        // Lose both: nothing painted, the handle gone.
        app.world_mut().resource_mut::<Selection>().labels = vec![FREE; n];
        app.world_mut().write_message(RegionsChanged { pose: None });
        app.update();
        assert!(app.world().resource::<Model>().handle.is_none());
        app.world_mut().write_message(FileCommand::LoadSetup);
        app.update();
        let _ = std::fs::remove_file(&path);
        let status = &app.world().resource::<StatusLine>().0;
        assert!(status.starts_with("loaded"), "{status}");
        assert_eq!(app.world().resource::<Selection>().labels, labels);
        let handle = app.world().resource::<Model>().handle.expect("a handle");
        let restored = app.world().get::<Transform>(handle).unwrap();
        assert!(
            restored.translation.distance(pose.translation) < 1e-6,
            "{restored:?}"
        );
        assert!(
            restored.rotation.angle_between(pose.rotation) < 1e-6,
            "{restored:?}"
        );
        let fixed = app.world().get::<FixedRegion>(entity).unwrap();
        assert_eq!(fixed.0, (0..8).collect::<Vec<u32>>());
        assert!(app.world().resource::<History>().can_undo());
    }
}
