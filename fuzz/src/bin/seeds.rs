//! Writes the fuzz targets' seed corpora: `seeds OUT_DIR REPO_ROOT`. The seeds are real files
//! and real bytes where the repository has them (the Fox, the task and mesh files, the shared
//! Wii Remote captures and meshes when `../shared` is there) and, for what it has no file of,
//! what the crate's own writers and device emulators produce (pad reports in each controller's
//! layout, a clip written by the glTF writer, a pose file, a VRM spring extension).

use std::path::{Path, PathBuf};

use bevy_wii_deform::controllers::pads::{EmulatedPad, PadEmulatorConfig};
use bevy_wii_deform::controllers::wiimote::protocol::{MotionPlusCalibration, OutputReport};
use bevy_wii_deform::controllers::wiimote::{EmulatedRemote, EmulatorConfig, Transport};
use bevy_wii_deform::controllers::{ControllerKind, Link};
use bevy_wii_deform::pose::rig::synth_rig::humanoid_rig;
use bevy_wii_deform::pose::{
    KeyInterpolation, PoseClip, PoseFile, PoseKey, write_bvh, write_gltf_clip,
};

/// The largest seed kept: libFuzzer's inputs grow from the seeds, and large ones slow it down.
const MAX_SEED: usize = 200_000;

struct Corpus {
    dir: PathBuf,
    count: usize,
}

impl Corpus {
    fn new(out: &Path, target: &str) -> Self {
        let dir = out.join(target);
        std::fs::create_dir_all(&dir).expect("cannot create the corpus folder");
        Self { dir, count: 0 }
    }

    fn add(&mut self, bytes: &[u8]) {
        let bytes = &bytes[..bytes.len().min(MAX_SEED)];
        self.count += 1;
        std::fs::write(self.dir.join(format!("seed-{:04}", self.count)), bytes)
            .expect("cannot write a seed");
    }

    fn add_file(&mut self, path: &Path) {
        if let Ok(bytes) = std::fs::read(path) {
            self.add(&bytes);
        }
    }
}

/// Every `"hex"` value of the shared captures' test vectors, and the hex lines of their text
/// captures, as bytes.
fn capture_bytes(shared: &Path) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    let parse = |s: &str| -> Option<Vec<u8>> {
        s.split_whitespace()
            .map(|t| u8::from_str_radix(t, 16).ok())
            .collect()
    };
    let captures = shared.join("wiimote/captures");
    if let Ok(text) = std::fs::read_to_string(captures.join("fixtures.json")) {
        for piece in text.split("\"hex\"").skip(1) {
            if let Some(value) = piece.split('"').nth(1)
                && let Some(bytes) = parse(value)
            {
                out.push(bytes);
            }
        }
    }
    for entry in std::fs::read_dir(&captures).into_iter().flatten().flatten() {
        let path = entry.path();
        if path.extension().is_some_and(|e| e == "txt") {
            for line in std::fs::read_to_string(&path).unwrap_or_default().lines() {
                if let Some((_, hex)) = line.split_once(':')
                    && let Some(bytes) = parse(hex)
                    && !bytes.is_empty()
                {
                    out.push(bytes);
                }
            }
        }
    }
    out
}

fn main() {
    let mut args = std::env::args_os().skip(1);
    let (Some(out), Some(root)) = (args.next(), args.next()) else {
        eprintln!("usage: seeds OUT_DIR REPO_ROOT");
        std::process::exit(2);
    };
    let (out, root) = (PathBuf::from(out), PathBuf::from(root));
    let shared = root.join("../shared");

    let mut wiimote = Corpus::new(&out, "wiimote_reports");
    for bytes in capture_bytes(&shared) {
        wiimote.add(&bytes);
    }
    wiimote.add(&MotionPlusCalibration::fallback().encode());
    let mut remote = EmulatedRemote::new(EmulatorConfig::default());
    for mode in [0x30u8, 0x31, 0x33, 0x35, 0x37, 0x3E] {
        let set = OutputReport::ReportMode {
            continuous: true,
            mode,
            ack: false,
            rumble: false,
        };
        let _ = remote.write(&set.encode());
        let mut buf = [0u8; 32];
        for _ in 0..3 {
            if let Ok(n) = remote.read_timeout(&mut buf, 20)
                && n > 0
            {
                wiimote.add(&buf[..n]);
            }
        }
    }

    let mut pads = Corpus::new(&out, "pad_reports");
    // The pads, in the order the target's first byte picks them (every kind but the remote).
    for (k, &kind) in ControllerKind::ALL[1..].iter().enumerate() {
        for (l, link) in [Link::Usb, Link::Bluetooth].into_iter().enumerate() {
            let mut pad = EmulatedPad::new(PadEmulatorConfig::new(kind, link));
            let mut feature = [0u8; 128];
            let id = bevy_wii_deform::controllers::sony::calibration_report(kind, link).0;
            feature[0] = id;
            let calibration = pad
                .get_feature_report(&mut feature)
                .map(|n| feature[..n].to_vec())
                .unwrap_or_default();
            let mut buf = [0u8; 128];
            for _ in 0..2 {
                if let Ok(n) = pad.read_timeout(&mut buf, 20)
                    && n > 0
                {
                    let mut seed = vec![(2 * k + l) as u8, calibration.len() as u8];
                    seed.extend_from_slice(&calibration);
                    seed.extend_from_slice(&buf[..n]);
                    pads.add(&seed);
                }
            }
        }
    }

    let mut meshes = Corpus::new(&out, "mesh_files");
    meshes.add_file(&root.join("assets/models/bar.obj"));
    meshes.add_file(&shared.join("meshes/cactus.off"));
    meshes.add(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1/1/1 -1 -2\n");
    meshes.add(b"OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n4 0 1 2 3\n");

    let mut selections = Corpus::new(&out, "selection_files");
    for file in ["cactus.sel", "cactus.def"] {
        if let Ok(bytes) = std::fs::read(shared.join("meshes").join(file)) {
            let mut seed = 620u16.to_le_bytes().to_vec();
            seed.extend(bytes);
            selections.add(&seed);
        }
    }
    selections.add(b"\x04\x00# 4 vertices\n0\n1\n2\n1\n");
    selections.add(b"\x00\x00# m\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");

    // glTF: the Fox (skin and clips), the static alien and the shared sphere, and a clip of
    // the generated humanoid written by the crate's own writer.
    let rig = humanoid_rig(2);
    let keys = [0.0f64, 0.4, -0.3]
        .into_iter()
        .enumerate()
        .map(|(k, angle)| {
            let mut pose = rig.rest.clone();
            for t in pose.local.iter_mut().skip(1).step_by(3) {
                t.rotation *= glam::DQuat::from_rotation_x(angle);
            }
            PoseKey {
                time: k as f32 * 0.5,
                pose,
                interpolation: KeyInterpolation::Linear,
            }
        });
    let clip = PoseClip::from_keys(keys.collect()).expect("three valid keys");
    let paths: Vec<Vec<String>> = rig
        .skeleton
        .joints()
        .iter()
        .map(|j| vec![j.name.clone()])
        .collect();
    let written = write_gltf_clip(&clip, "wave", &paths, Some(&rig.rest)).ok();
    for target in ["gltf_character", "gltf_clip", "vrm_springs"] {
        let mut corpus = Corpus::new(&out, target);
        corpus.add_file(&root.join("assets/models/Fox.glb"));
        corpus.add_file(&root.join("assets/models/alien.glb"));
        corpus.add_file(&shared.join("models/sphere.gltf"));
        if let Some(bytes) = &written {
            corpus.add(bytes);
        }
        if target == "vrm_springs" {
            corpus.add(vrm_seed(&rig.skeleton).as_bytes());
        }
    }

    let mut ron = Corpus::new(&out, "ron_files");
    if let Ok(text) = PoseFile::from_pose(&rig.skeleton, &rig.rest).to_ron() {
        ron.add(text.as_bytes());
    }
    for entry in std::fs::read_dir(root.join("assets/tasks"))
        .into_iter()
        .flatten()
        .flatten()
    {
        ron.add_file(&entry.path());
    }
    let names = |k: usize| {
        rig.skeleton.joints()[k.min(rig.skeleton.len() - 1)]
            .name
            .clone()
    };
    ron.add(
        format!(
            "(joints: {{ {:?}: Hinge(axis: (1.0, 0.0, 0.0), min_deg: 0.0, max_deg: 150.0), \
             {:?}: SwingTwist(swing_deg: (40.0, 30.0), twist_deg: (-50.0, 50.0)) }})",
            names(3),
            names(2)
        )
        .as_bytes(),
    );
    ron.add(
        format!(
            "(chains: [(name: \"tail\", joints: [{:?}, {:?}], stiffness: 1.2)], \
             colliders: [(joint: {:?}, radius: 0.1)])",
            names(1),
            names(2),
            names(0)
        )
        .as_bytes(),
    );
    ron.add(b"Wave pose");
    let mut bvh = Corpus::new(&out, "bvh_files");
    if let Ok(text) = write_bvh(&rig.skeleton, &rig.rest, &clip, 1.0 / 30.0) {
        bvh.add(text.as_bytes());
    }
    bvh.add(CMU_STYLE.as_bytes());
    ron.add(b"../../etc/passwd");
}

/// A `VRMC_springBone` extension over a chain of the humanoid's joints (nodes named like
/// them), in the layout VRM 1.0 exporters write.
fn vrm_seed(skeleton: &bevy_wii_deform::pose::Skeleton) -> String {
    let chain: Vec<usize> = {
        let mut chain = vec![0];
        while let Some(&child) = skeleton.children(*chain.last().unwrap_or(&0)).first() {
            chain.push(child);
            if chain.len() == 4 {
                break;
            }
        }
        chain
    };
    let nodes: Vec<String> = chain
        .iter()
        .enumerate()
        .map(|(k, &j)| {
            let child = if k + 1 < chain.len() {
                format!(r#","children":[{}]"#, k + 1)
            } else {
                String::new()
            };
            format!(
                r#"{{"name":{:?},"translation":[0.0,0.1,0.0]{child}}}"#,
                skeleton.joints()[j].name
            )
        })
        .collect();
    let joints: Vec<String> = (1..chain.len())
        .map(|k| format!(r#"{{"node":{k},"hitRadius":0.01,"stiffness":0.8,"gravityPower":0.5,"gravityDir":[0.0,-1.0,0.0],"dragForce":0.3}}"#))
        .collect();
    format!(
        r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":["VRMC_springBone"],"nodes":[{}],
"extensions":{{"VRMC_springBone":{{"specVersion":"1.0",
"colliders":[{{"node":0,"shape":{{"sphere":{{"offset":[0.0,0.0,0.1],"radius":0.05}}}}}},
{{"node":0,"shape":{{"capsule":{{"offset":[0.0,0.0,0.0],"tail":[0.0,0.2,0.0],"radius":0.02}}}}}}],
"colliderGroups":[{{"name":"head","colliders":[0,1]}}],
"springs":[{{"name":"hair","joints":[{}],"colliderGroups":[0],"center":0}}]}}}}}}"#,
        nodes.join(","),
        joints.join(",")
    )
}

/// A hierarchy in the layout of the CMU library's BVH exports (six root channels, three per
/// joint, End Sites), two frames.
const CMU_STYLE: &str = "HIERARCHY
ROOT Hips
{
  OFFSET 0.0 0.0 0.0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT LHipJoint
  {
    OFFSET 0 0 0
    CHANNELS 0
    JOINT LeftUpLeg
    {
      OFFSET 1.36 -1.79 0.84
      CHANNELS 3 Zrotation Yrotation Xrotation
      JOINT LeftLeg
      {
        OFFSET 2.45 -6.72 0.0
        CHANNELS 3 Zrotation Yrotation Xrotation
        End Site
        {
          OFFSET 2.5 -6.9 0.0
        }
      }
    }
  }
  JOINT LowerBack
  {
    OFFSET 0 0 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET -0.05 2.0 -0.1
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.008333
9.37 17.8 -17.7 -3.5 -6.6 -3.9 -6.4 -12.9 4.3 27.1 0 0 1.2 0.4 0.7
9.38 17.8 -17.7 -3.5 -6.6 -3.9 -6.5 -13.0 4.4 27.3 0 0 1.2 0.4 0.6
";
