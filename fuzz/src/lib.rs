//! The fuzz targets of `bevy_wii_deform`: one function per entry point that takes bytes from
//! outside (controller reports, mesh and selection files, glTF characters, clips and spring
//! bones, RON files). Each feeds the crate's own reader and then checks what the crate
//! promises of a reader's result — a typed error or a valid value, no NaN in a mesh, a joint or
//! a motion sample. A panic, a hang or a runaway allocation is a finding.
//!
//! `fuzz_targets/` wraps each function for libFuzzer (`bash fuzz/run.sh`), and the main
//! crate's `cargo test` replays the inputs kept in `tests/fuzz_regressions/<target>/` through
//! [`run`].

use std::sync::OnceLock;

use bevy_wii_deform::controllers::pads::{PadCalibration, PadDecoder};
use bevy_wii_deform::controllers::sony::SonyCalibration;
use bevy_wii_deform::controllers::switch::{CalibrationSource, SwitchCalibration};
use bevy_wii_deform::controllers::wiimote::ir;
use bevy_wii_deform::controllers::wiimote::protocol::{
    AccelCalibration, ExtensionId, InputReport, MotionPlusCalibration, MotionPlusFrame,
    OutputReport, classify_extension,
};
use bevy_wii_deform::controllers::{ControllerKind, Link, PadReport};
use bevy_wii_deform::deform::{TriMesh, VertexSelection, parse_handle_transform};
use bevy_wii_deform::pose::rig::synth_rig::{SyntheticRig, humanoid_rig};
use bevy_wii_deform::pose::{
    GltfCharacter, GltfFile, JointLimits, ModelSettings, PoseClip, PoseFile, PoseLibrary, Skeleton,
    SkeletonPose, SpringRig, read_bvh, read_gltf_clip, read_vrm_springs, write_bvh,
};

/// A fuzz target: bytes in, a panic on a finding.
pub type Target = fn(&[u8]);

/// The targets, by the names `fuzz/run.sh` and the regression folders use.
pub const TARGETS: [(&str, Target); 9] = [
    ("wiimote_reports", wiimote_reports),
    ("pad_reports", pad_reports),
    ("mesh_files", mesh_files),
    ("selection_files", selection_files),
    ("gltf_character", gltf_character),
    ("gltf_clip", gltf_clip),
    ("vrm_springs", vrm_springs),
    ("ron_files", ron_files),
    ("bvh_files", bvh_files),
];

/// Runs target `name` on `data`; `false` when there is no such target.
pub fn run(name: &str, data: &[u8]) -> bool {
    match TARGETS.iter().find(|(n, _)| *n == name) {
        Some((_, target)) => {
            target(data);
            true
        }
        None => false,
    }
}

/// The Wii Remote: the bytes as an input report (data reports' extension bytes classified
/// with and without a MotionPlus, their IR bytes decoded), as an output report (what the
/// emulator reads from a host), as calibration blocks (accelerometer, MotionPlus) and as an
/// extension id.
pub fn wiimote_reports(data: &[u8]) {
    if let Ok(InputReport::Data {
        accel,
        extension,
        ir: camera,
        ..
    }) = InputReport::decode(data)
    {
        if let Some(e) = extension {
            let _ = classify_extension(&e, true);
            let _ = classify_extension(&e, false);
            if let Ok(frame) = MotionPlusFrame::decode(&e) {
                let rates = MotionPlusCalibration::fallback().rates_deg(&frame);
                assert!(rates.is_finite());
            }
        }
        if let Some(bytes) = camera {
            let _ = ir::decode_basic(&bytes);
            let _ = ir::decode_extended(&bytes);
        }
        if let Some(raw) = accel {
            assert!(AccelCalibration::default().to_g(raw).is_finite());
        }
    }
    let _ = ir::Report37::parse(data);
    let _ = ir::decode_full(data);
    let _ = OutputReport::decode(data);
    let _ = ExtensionId::parse(data);
    if let Some(calibration) = AccelCalibration::parse(data) {
        assert!(
            calibration
                .to_g(bevy_wii_deform::controllers::wiimote::protocol::AccelRaw(
                    [512; 3]
                ))
                .is_finite(),
            "a parsed accelerometer calibration gives non-finite accelerations"
        );
    }
    if data.len() >= 20 {
        let (calibration, _) = AccelCalibration::from_blocks(&data[..10], &data[10..20]);
        let g = calibration.to_g(bevy_wii_deform::controllers::wiimote::protocol::AccelRaw([
            0, 1023, 512,
        ]));
        assert!(g.is_finite(), "accelerometer blocks give {g}");
    }
    if let Ok((calibration, _)) = MotionPlusCalibration::parse(data) {
        let frame = MotionPlusFrame::decode(&[0x7f, 0x7f, 0x7f, 0xff, 0xff, 0xff]);
        if let Ok(frame) = frame {
            let rates = calibration.rates_deg(&frame);
            assert!(
                rates.is_finite(),
                "a parsed MotionPlus calibration gives {rates}"
            );
        }
    }
}

/// A motion sample or report the app would act on must be finite.
fn check_pad_report(report: &PadReport) {
    for s in report.samples() {
        assert!(
            s.gyro_rps.is_finite() && s.accel_mps2.is_finite(),
            "a decoded sample is not finite: {s:?}"
        );
        assert!(s.device_time_s.is_none_or(f64::is_finite));
    }
}

/// DualSense, DualSense Edge, DualShock 4 and Switch controllers: the first byte picks the
/// controller and the link, the second how long the calibration block is; the calibration
/// (a Sony feature report or a Switch SPI block) is parsed from those bytes and the rest is
/// decoded as an input report with it (and with the datasheet values), and as a Switch
/// subcommand reply.
pub fn pad_reports(data: &[u8]) {
    let [pick, split, rest @ ..] = data else {
        return;
    };
    // The pads: every kind but the Wii Remote (first in the list).
    let pads = &ControllerKind::ALL[1..];
    let kind = pads[(*pick as usize % (2 * pads.len())) / 2];
    let link = if pick % 2 == 0 {
        Link::Usb
    } else {
        Link::Bluetooth
    };
    let (block, report) = rest.split_at((*split as usize).min(rest.len()));
    let Ok(mut decoder) = PadDecoder::new(kind, link) else {
        return;
    };
    if let Ok(report) = decoder.decode(report) {
        check_pad_report(&report);
    }
    let calibration = match kind {
        ControllerKind::DualSense | ControllerKind::DualSenseEdge | ControllerKind::DualShock4 => {
            SonyCalibration::parse(kind, link, block)
                .map(PadCalibration::Sony)
                .ok()
        }
        _ => {
            let _ = bevy_wii_deform::controllers::switch::parse_reply(report);
            SwitchCalibration::from_block(block, CalibrationSource::Factory)
                .map(PadCalibration::Switch)
                .ok()
        }
    };
    if let Some(calibration) = calibration {
        decoder.set_calibration(calibration);
        if let Ok(report) = decoder.decode(report) {
            check_pad_report(&report);
        }
    }
}

/// OBJ and OFF meshes: a mesh that parses has finite positions and triangles of its vertices.
pub fn mesh_files(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    for mesh in [TriMesh::parse_obj(text), TriMesh::parse_off(text)]
        .into_iter()
        .flatten()
    {
        assert!(mesh.positions.iter().all(|p| p.is_finite()));
        let n = mesh.positions.len() as u32;
        assert!(mesh.triangles.iter().flatten().all(|&i| i < n));
    }
}

/// The deformation benchmark's `.sel` (the first two bytes: the mesh's vertex count) and
/// `.def` files.
pub fn selection_files(data: &[u8]) {
    let [a, b, rest @ ..] = data else {
        return;
    };
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    let count = u16::from_le_bytes([*a, *b]) as usize;
    if let Ok(selection) = VertexSelection::parse_sel(text, count) {
        assert_eq!(selection.roles.len(), count);
    }
    if let Ok(transform) = parse_handle_transform(text) {
        assert!(transform.matrix3.is_finite() && transform.translation.is_finite());
    }
}

/// A skeleton and rest pose to read files against when the file brings none: the generated
/// humanoid (Mixamo-style names).
fn humanoid() -> &'static SyntheticRig {
    static RIG: OnceLock<SyntheticRig> = OnceLock::new();
    RIG.get_or_init(|| humanoid_rig(2))
}

/// The most vertices a fuzzed character is prepared for posing with (the preparation is
/// linear in them; bigger ones are only read).
const MODEL_VERTICES: usize = 4096;

/// A glTF/GLB character through the crate's reading: the skeleton, the skin, the rest pose,
/// and (for small meshes) the model prepared for posing and skinned at rest.
pub fn gltf_character(data: &[u8]) {
    let Ok(character) = bevy_wii_deform::pose::read_gltf_character(data, None) else {
        return;
    };
    let joints = character.skeleton.len();
    assert!(joints > 0 && character.rest.local.len() == joints);
    assert!(character.rest.local.iter().all(|t| t.is_valid()));
    let n = character.mesh.positions.len() as u32;
    assert!(character.mesh.indices.iter().all(|&i| i < n));
    if character.mesh.positions.len() <= MODEL_VERTICES {
        let settings = ModelSettings {
            clusters: 16,
            ..ModelSettings::default()
        };
        if let Ok(model) = character.model(settings) {
            let skinned = model.skin_render(&character.rest);
            // Positions a file gives may be huge but finite; skinning them stays finite only
            // when the matrices are moderate, so only a NaN is a finding.
            assert!(
                skinned.iter().all(|p| !p.is_nan()),
                "NaN in a skinned rest shape"
            );
        }
    }
}

/// The file's character (if it has one) or the generated humanoid, for the clip and spring
/// readers.
fn skeleton_for(data: &[u8]) -> (Skeleton, SkeletonPose) {
    match GltfFile::parse(data, None)
        .ok()
        .and_then(|f| GltfCharacter::from_file(&f).ok())
    {
        Some(c) => (c.skeleton, c.rest),
        None => (humanoid().skeleton.clone(), humanoid().rest.clone()),
    }
}

/// Every pose a clip plays is valid: sampled at its keys, between them and past both ends.
fn check_clip(clip: &PoseClip) {
    let keys = clip.keys();
    let mut times: Vec<f32> = keys.iter().map(|k| k.time).collect();
    times.extend(keys.windows(2).map(|w| 0.5 * (w[0].time + w[1].time)));
    if let (Some(first), Some(last)) = (keys.first(), keys.last()) {
        times.extend([first.time - 1.0, last.time + 1.0]);
    }
    for t in times.into_iter().take(64) {
        if let Some(pose) = clip.sample(t) {
            assert!(
                pose.local.iter().all(|j| j.is_valid()),
                "the clip plays an invalid pose at {t}"
            );
        }
    }
}

/// A glTF clip read onto the file's own skeleton (or the humanoid), and sampled.
pub fn gltf_clip(data: &[u8]) {
    let (skeleton, rest) = skeleton_for(data);
    if let Ok(clip) = read_gltf_clip(data, None, None, &skeleton, &rest) {
        check_clip(&clip);
    }
}

/// VRM spring bones (`VRMC_springBone`) read onto the file's skeleton (or the humanoid).
pub fn vrm_springs(data: &[u8]) {
    let (skeleton, _) = skeleton_for(data);
    if let Ok(rig) = read_vrm_springs(data, &skeleton) {
        assert!(
            rig.validate(&skeleton).is_ok(),
            "a read spring rig does not validate"
        );
    }
}

/// RON files against the humanoid: a pose file (applied), joint limits, a spring rig, and the
/// text as a pose library's pose name (which must stay inside the library's folder).
pub fn ron_files(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let rig = humanoid();
    if let Ok(file) = PoseFile::from_ron(text)
        && let Ok(pose) = file.apply(&rig.skeleton, &rig.rest)
    {
        assert!(
            pose.local.iter().all(|t| t.is_valid()),
            "a pose file applied to an invalid pose"
        );
    }
    if let Ok(limits) = JointLimits::from_ron(text, &rig.skeleton, &rig.rest) {
        let mut pose = rig.rest.clone();
        limits.project(&mut pose);
        assert!(
            pose.local.iter().all(|t| t.is_valid()),
            "limits project to an invalid pose"
        );
    }
    if let Ok(springs) = SpringRig::from_ron(text, &rig.skeleton) {
        assert!(springs.validate(&rig.skeleton).is_ok());
    }
    let library = PoseLibrary::new("/nonexistent/pose-library");
    if let Err(bevy_wii_deform::pose::PoseFileError::Io { path, .. }) = library.load(text) {
        assert!(
            std::path::Path::new(&path).starts_with(library.folder()),
            "pose name {text:?} reads {path}, outside the library"
        );
    }
}

/// Motion capture: a BVH file read (skeleton, rest pose, frames), its clip played, and written
/// back and read again (the writer must accept whatever the reader gives).
pub fn bvh_files(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(motion) = read_bvh(text) else {
        return;
    };
    assert!(motion.rest.local.iter().all(|t| t.is_valid()));
    check_clip(&motion.clip);
    if motion.clip.keys().len() <= 64 {
        let written = write_bvh(
            &motion.skeleton,
            &motion.rest,
            &motion.clip,
            motion.frame_time,
        )
        .expect("a clip read from BVH writes back");
        let again = read_bvh(&written).expect("a written BVH reads back");
        assert_eq!(again.clip.keys().len(), motion.clip.keys().len());
    }
}
