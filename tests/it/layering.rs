//! The layers of the source tree: `src/pose`'s folders import only the folders below them
//! (rig ← ground ← constraints ← solver; animation on rig; springs on rig and constraints;
//! retarget on all but springs), `src/controllers`' device folders import the shared layer and
//! never each other (the pads' session imports its two families; the manager every device),
//! and no core imports the ECS layer. Read from the `use` lines and paths of the sources
//! themselves (test modules inside a file are left out: tests may reach anywhere).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use crate::common::scratch::ScratchDir;

/// Every `.rs` file under `dir`, recursively.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).expect("a source folder") {
            let path = entry.expect("a folder entry").path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// The code of a file without its comments and without its `#[cfg(test)]` tail.
fn code_of(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap_or("");
    text.lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The module path of a source file below `src/`, as segments (`src/pose/rig/mod.rs` →
/// `["pose", "rig"]`).
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).expect("a file under src");
    let mut segs: Vec<String> = rel
        .with_extension("")
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if segs.last().is_some_and(|s| s == "mod" || s == "lib") {
        segs.pop();
    }
    segs
}

/// `code` with the whitespace around `::`, braces and commas taken out (so a `use` tree
/// written over several lines reads as one path), other runs of whitespace kept as one space.
fn compact(code: &str) -> Vec<char> {
    let chars: Vec<char> = code.chars().collect();
    let glue = |c: char| matches!(c, ':' | '{' | '}' | ',');
    let mut out: Vec<char> = Vec::with_capacity(chars.len());
    let mut i = 0;
    while i < chars.len() {
        if chars[i].is_whitespace() {
            let mut j = i;
            while j < chars.len() && chars[j].is_whitespace() {
                j += 1;
            }
            let before = out.last().copied();
            let after = chars.get(j).copied();
            if !(before.is_some_and(glue) || after.is_some_and(glue)) {
                out.push(' ');
            }
            i = j;
        } else {
            out.push(chars[i]);
            i += 1;
        }
    }
    out
}

/// Every path a file's code names: `crate::a::b…` as `[a, b, …]`, `super::…` resolved against
/// the file's module, with `{…}` groups of `use` lines expanded to their first segment.
fn paths_named(code: &str, module: &[String]) -> Vec<Vec<String>> {
    let text = compact(code);
    let ident_char = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let starts = |at: usize, word: &str| {
        word.chars()
            .enumerate()
            .all(|(k, w)| text.get(at + k) == Some(&w))
    };
    let ident_at = |at: usize| -> String {
        text[at.min(text.len())..]
            .iter()
            .take_while(|c| ident_char(**c))
            .collect()
    };
    let mut out = Vec::new();
    let mut i = 0;
    while i < text.len() {
        let boundary = i == 0 || !(ident_char(text[i - 1]) || text[i - 1] == ':');
        let (mut segs, mut j) = if boundary && starts(i, "crate::") {
            (Vec::new(), i + "crate::".len())
        } else if boundary && starts(i, "super::") {
            let mut base = module.to_vec();
            let mut j = i;
            while starts(j, "super::") {
                base.pop();
                j += "super::".len();
            }
            (base, j)
        } else {
            i += 1;
            continue;
        };
        loop {
            let ident = ident_at(j);
            if ident.is_empty() {
                // a `{a::x, b::y}` group: each member's first segment
                if text.get(j) == Some(&'{') {
                    let end = (j..text.len())
                        .find(|&e| text[e] == '}')
                        .unwrap_or(text.len());
                    let group: String = text[j + 1..end].iter().collect();
                    for member in group.split(',') {
                        let first: String = member.chars().take_while(|c| ident_char(*c)).collect();
                        if !first.is_empty() {
                            let mut p = segs.clone();
                            p.push(first);
                            out.push(p);
                        }
                    }
                }
                break;
            }
            j += ident.len();
            segs.push(ident);
            if starts(j, "::") {
                j += 2;
            } else {
                break;
            }
        }
        out.push(segs);
        i = j.max(i + 1);
    }
    out
}

/// The folder of `src/pose` a module belongs to (`None` for the root's own files).
fn pose_folder(module: &[String]) -> Option<&str> {
    match module {
        [first, folder, ..] if first == "pose" && folder != "error" => Some(folder.as_str()),
        _ => None,
    }
}

/// Which folders of `src/pose` each folder may import.
fn allowed() -> BTreeMap<&'static str, &'static [&'static str]> {
    BTreeMap::from([
        ("rig", &[][..]),
        ("ground", &["rig"][..]),
        ("constraints", &["rig", "ground"][..]),
        ("solver", &["rig", "ground", "constraints"][..]),
        ("animation", &["rig"][..]),
        ("springs", &["rig", "constraints"][..]),
        (
            "retarget",
            &["rig", "ground", "constraints", "solver", "animation"][..],
        ),
    ])
}

/// The imports between `src/pose`'s folders that break the layer order, as
/// `file: folder → folder (path)`; also every import of a root re-export from inside a
/// folder (which hides the folder it comes from).
fn pose_layer_violations(src: &Path) -> Vec<String> {
    let allowed = allowed();
    let mut bad = Vec::new();
    for file in rust_files(&src.join("pose")) {
        let module = module_of(src, &file);
        let Some(from) = pose_folder(&module) else {
            continue;
        };
        let code = code_of(&std::fs::read_to_string(&file).expect("a source file"));
        for path in paths_named(&code, &module) {
            if path.first().is_none_or(|p| p != "pose") || path.len() < 2 {
                continue;
            }
            let to = path[1].as_str();
            let shown = format!("{}: {from} → {to} ({})", file.display(), path.join("::"));
            match allowed.get(to) {
                Some(_) if to == from => {}
                Some(_) if allowed[from].contains(&to) => {}
                Some(_) => bad.push(shown),
                None if to == "error" || to == "PoseError" => {}
                None => bad.push(format!("{shown}: a root re-export, name the folder")),
            }
        }
    }
    bad
}

fn src_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// The pose layer's folders import only the folders below them.
#[test]
fn pose_folders_import_only_the_layers_below_them() {
    let bad = pose_layer_violations(&src_dir());
    assert!(
        bad.is_empty(),
        "imports against the layer order:\n{}",
        bad.join("\n")
    );
}

/// The layer table has no cycle, so following it never comes back to a folder.
#[test]
fn the_pose_layer_order_has_no_cycle() {
    let allowed = allowed();
    for start in allowed.keys() {
        let mut seen = BTreeSet::new();
        let mut stack: Vec<&str> = allowed[start].to_vec();
        while let Some(f) = stack.pop() {
            assert_ne!(f, *start, "{start} reaches itself");
            if seen.insert(f) {
                stack.extend(allowed[f].iter().copied());
            }
        }
    }
}

/// The checker itself: an import of the solver from the rig, and one through a root
/// re-export, are both found in a source tree made for the purpose.
#[test]
fn an_import_against_the_order_is_found() {
    let dir = ScratchDir::new("layering");
    let rig = dir.join("pose").join("rig");
    std::fs::create_dir_all(&rig).unwrap();
    std::fs::write(
        rig.join("model.rs"),
        "use crate::pose::solver::PoseSolver;\nuse super::super::Skeleton;\n\
         use crate::pose::rig::skeleton::Joint;\n#[cfg(test)]\nmod tests { use crate::pose::ground::Floor; }\n",
    )
    .unwrap();
    let bad = pose_layer_violations(&dir);
    assert_eq!(bad.len(), 2, "{bad:?}");
    assert!(bad[0].contains("rig → solver"), "{bad:?}");
    assert!(bad[1].contains("root re-export"), "{bad:?}");
}

/// The tier of `src/controllers` a path below it names: `shared` for the layer every
/// controller uses (its files, `session/`, `emulation/`, `fusion/` and the root's
/// re-exports), else the device folder (`wiimote`, `sony`, `switch`), `pads` or `manager`.
fn controller_tier(segment: &str) -> &str {
    match segment {
        "wiimote" | "sony" | "switch" | "pads" | "manager" => segment,
        _ => "shared",
    }
}

/// Which tiers of `src/controllers` each tier may import.
fn controller_tiers_allowed() -> BTreeMap<&'static str, &'static [&'static str]> {
    BTreeMap::from([
        ("shared", &["shared"][..]),
        ("wiimote", &["shared"][..]),
        ("sony", &["shared"][..]),
        ("switch", &["shared"][..]),
        ("pads", &["shared", "sony", "switch"][..]),
        ("manager", &["shared", "wiimote", "pads"][..]),
    ])
}

/// The imports between `src/controllers`' tiers against [`controller_tiers_allowed`], as
/// `file: tier → tier (path)`.
fn controller_layer_violations(src: &Path) -> Vec<String> {
    let allowed = controller_tiers_allowed();
    let mut bad = Vec::new();
    for file in rust_files(&src.join("controllers")) {
        let module = module_of(src, &file);
        let from = module.get(1).map_or("shared", |s| controller_tier(s));
        let code = code_of(&std::fs::read_to_string(&file).expect("a source file"));
        for path in paths_named(&code, &module) {
            if path.first().is_none_or(|p| p != "controllers") || path.len() < 2 {
                continue;
            }
            let to = controller_tier(&path[1]);
            if to != from && !allowed[from].contains(&to) {
                bad.push(format!(
                    "{}: {from} → {to} ({})",
                    file.display(),
                    path.join("::")
                ));
            }
        }
    }
    bad
}

/// The controllers' device folders import the shared layer, never each other; the shared
/// layer imports no device.
#[test]
fn controller_devices_import_only_the_shared_layer() {
    let bad = controller_layer_violations(&src_dir());
    assert!(
        bad.is_empty(),
        "imports between controller tiers:\n{}",
        bad.join("\n")
    );
}

/// The checker finds a device importing another device and the shared layer importing a
/// device, in a source tree made for the purpose.
#[test]
fn an_import_between_controller_devices_is_found() {
    let dir = ScratchDir::new("controller_layering");
    let sony = dir.join("controllers").join("sony");
    std::fs::create_dir_all(&sony).unwrap();
    std::fs::write(
        sony.join("mod.rs"),
        "use crate::controllers::wiimote::Buttons;\nuse super::session::SessionEvent;\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("controllers").join("transport.rs"),
        "use crate::controllers::{ControllerKind, pads::PadSession};\n",
    )
    .unwrap();
    let bad = controller_layer_violations(&dir);
    assert_eq!(bad.len(), 2, "{bad:?}");
    assert!(bad.iter().any(|b| b.contains("sony → wiimote")), "{bad:?}");
    assert!(bad.iter().any(|b| b.contains("shared → pads")), "{bad:?}");
}

/// No core layer (deform, pose, controllers, history) imports the ECS layer or Bevy.
#[test]
fn the_cores_import_neither_the_ecs_layer_nor_bevy() {
    let src = src_dir();
    let mut bad = Vec::new();
    for core in ["deform", "pose", "controllers"] {
        for file in rust_files(&src.join(core)) {
            let module = module_of(&src, &file);
            let code = code_of(&std::fs::read_to_string(&file).unwrap());
            if paths_named(&code, &module)
                .iter()
                .any(|p| p.first().is_some_and(|s| s == "ecs"))
            {
                bad.push(format!("{}: imports the ECS layer", file.display()));
            }
            if code.contains("bevy::") || code.contains("use bevy") {
                bad.push(format!("{}: uses Bevy", file.display()));
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// Every folder's `mod.rs` (and `lib.rs` for `src/`) names each of its files and subfolders in
/// its opening documentation (as `` `file.rs` ``, `folder/` or a link to the module): the map a
/// newcomer reads first is complete.
#[test]
fn every_folder_map_names_its_files() {
    let src = src_dir();
    let mut missing = Vec::new();
    let mut stack = vec![src.clone()];
    while let Some(dir) = stack.pop() {
        let map = if dir == src { "lib.rs" } else { "mod.rs" };
        let Ok(text) = std::fs::read_to_string(dir.join(map)) else {
            continue;
        };
        let doc: String = text
            .lines()
            .filter(|l| l.starts_with("//!"))
            .collect::<Vec<_>>()
            .join("\n");
        for entry in std::fs::read_dir(&dir).expect("a source folder") {
            let path = entry.expect("a folder entry").path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            let stem = name.trim_end_matches(".rs");
            let linked = doc.contains(&format!("[`{stem}`]"));
            let named = if path.is_dir() {
                stack.push(path.clone());
                linked || doc.contains(&format!("{name}/"))
            } else {
                name == map
                    || !name.ends_with(".rs")
                    || linked
                    || doc.contains(&format!("`{name}`"))
            };
            if !named {
                missing.push(format!("{}: {name}", dir.join(map).display()));
            }
        }
    }
    assert!(
        missing.is_empty(),
        "not in the folder's map:\n{}",
        missing.join("\n")
    );
}
