//! Broken glTF files made on the spot for tests (the integration tests' `malformed_gltf` and
//! the sandbox's loading test): indices out of range, NaN and infinite positions, bad
//! normals, a missing `.bin`, recursive nodes, no scene, wrong JSON types, not JSON at all.

use std::path::PathBuf;

/// A quad (two triangles) as positions, normals and u16 indices in one buffer.
fn buffer(positions: &[[f32; 3]], normals: &[[f32; 3]], indices: &[u16]) -> Vec<u8> {
    let mut bytes = Vec::new();
    for p in positions.iter().chain(normals) {
        for v in p {
            bytes.extend(v.to_le_bytes());
        }
    }
    for i in indices {
        bytes.extend(i.to_le_bytes());
    }
    bytes
}

const QUAD: [[f32; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
];
const UP: [[f32; 3]; 4] = [[0.0, 0.0, 1.0]; 4];

/// The glTF JSON of one mesh node referring to `uri` (48 + 48 + 12 bytes).
fn gltf_json(uri: &str, nodes: &str, scenes: &str) -> String {
    format!(
        r#"{{
  "asset": {{ "version": "2.0" }},
  "buffers": [{{ "uri": "{uri}", "byteLength": 108 }}],
  "bufferViews": [
    {{ "buffer": 0, "byteOffset": 0, "byteLength": 48 }},
    {{ "buffer": 0, "byteOffset": 48, "byteLength": 48 }},
    {{ "buffer": 0, "byteOffset": 96, "byteLength": 12 }}
  ],
  "accessors": [
    {{ "bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
       "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0] }},
    {{ "bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3" }},
    {{ "bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR" }}
  ],
  "meshes": [{{ "primitives": [{{ "attributes": {{ "POSITION": 0, "NORMAL": 1 }}, "indices": 2 }}] }}],
  "nodes": {nodes},
  "scenes": {scenes},
  "scene": 0
}}"#
    )
}

const ONE_NODE: &str = r#"[{ "mesh": 0 }]"#;
const ONE_SCENE: &str = r#"[{ "nodes": [0] }]"#;

/// Writes the test files into a fresh folder named `name` in the temporary directory; returns
/// it and the files' names with whether the file is still usable (a mesh that works) rather
/// than broken.
pub fn write_files(name: &str) -> (PathBuf, Vec<(&'static str, bool)>) {
    let dir = std::env::temp_dir().join(format!("{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let write = |name: &str, bytes: &[u8]| std::fs::write(dir.join(name), bytes).unwrap();
    let good = [0u16, 1, 2, 0, 2, 3];
    write("good.bin", &buffer(&QUAD, &UP, &good));
    write("far_index.bin", &buffer(&QUAD, &UP, &[0, 1, 2, 0, 2, 40]));
    let mut nan = QUAD;
    nan[2][1] = f32::NAN;
    write("nan.bin", &buffer(&nan, &UP, &good));
    let mut inf = QUAD;
    inf[1][0] = f32::INFINITY;
    write("inf.bin", &buffer(&inf, &UP, &good));
    write(
        "bad_normals.bin",
        &buffer(&QUAD, &[[0.0; 3], [f32::NAN; 3], [0.0; 3], [0.0; 3]], &good),
    );
    let json = |uri: &str, nodes: &str, scenes: &str| gltf_json(uri, nodes, scenes).into_bytes();
    write("good.gltf", &json("good.bin", ONE_NODE, ONE_SCENE));
    write(
        "far_index.gltf",
        &json("far_index.bin", ONE_NODE, ONE_SCENE),
    );
    write("nan.gltf", &json("nan.bin", ONE_NODE, ONE_SCENE));
    write("inf.gltf", &json("inf.bin", ONE_NODE, ONE_SCENE));
    write(
        "bad_normals.gltf",
        &json("bad_normals.bin", ONE_NODE, ONE_SCENE),
    );
    write(
        "missing_bin.gltf",
        &json("missing.bin", ONE_NODE, ONE_SCENE),
    );
    write(
        "recursive.gltf",
        &json(
            "good.bin",
            r#"[{ "mesh": 0, "children": [1] }, { "children": [0] }]"#,
            ONE_SCENE,
        ),
    );
    write(
        "no_scene.gltf",
        gltf_json("good.bin", ONE_NODE, "[]")
            .replace("\"scene\": 0", "\"extras\": {}")
            .as_bytes(),
    );
    write(
        "wrong_types.gltf",
        &json("good.bin", r#""oops""#, ONE_SCENE),
    );
    write("not_json.gltf", b"{ this is not json");
    let files = vec![
        ("good.gltf", true),
        ("bad_normals.gltf", true),
        ("far_index.gltf", false),
        ("nan.gltf", false),
        ("inf.gltf", false),
        ("missing_bin.gltf", false),
        ("recursive.gltf", false),
        ("no_scene.gltf", false),
        ("wrong_types.gltf", false),
        ("not_json.gltf", false),
    ];
    (dir, files)
}
