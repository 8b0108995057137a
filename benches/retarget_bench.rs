//! Retargeting a clip from one skeleton onto another through the pose solver
//! (`pose::retarget`): the source a glTF/GLB character's clip or a BVH file, the target any
//! rigged glTF. Bakes the clip with the contacts kept and again without, in one process,
//! streams the same frames through the live path one at a time, and prints what was mapped,
//! the bake's and a live frame's cost and the bake's quality as JSON (the last line).
//!
//! ```sh
//! cargo run --release --example retarget_bench -- --source assets/models/Fox.glb --clip Walk \
//!     --target assets/models/Fox.glb --map assets/retarget/fox.ron --stretch-legs 1.3 --json
//! ```
//!
//! `--stretch-legs F` makes the target's legs (the map's foot chains) F times as long before
//! the retarget — bones, bind pose and skin — so one file gives a differently proportioned
//! target. Without `--map` the skeletons are mapped as humanoids by their joints' names.

use bevy_wii_deform_examples::cli;

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use bevy_wii_deform::pose::retarget::{
    RetargetSettings, Retargeter, SkeletonMap, read_source_motion,
};
use bevy_wii_deform::pose::{
    GltfCharacter, GroundPlane, Joint, ModelSettings, PoseClip, Skeleton, SkeletonPose, SkinnedMesh,
};
use glam::{DAffine3, DVec3};

const USAGE: &str = "usage: retarget_bench --source PATH [--clip NAME] --target PATH [--map FILE] \
[--ground flat] [--no-contacts] [--stretch-legs F] [--json]";

struct Args {
    source: PathBuf,
    clip: Option<String>,
    target: PathBuf,
    map: Option<PathBuf>,
    contacts: bool,
    stretch_legs: f64,
}

fn args() -> Args {
    let mut parser = cli::Parser::from_env();
    let (mut source, mut target, mut clip, mut map) = (None, None, None, None);
    let (mut contacts, mut stretch_legs) = (true, 1.0);
    while let Some(arg) = cli::next(&mut parser, USAGE) {
        match arg {
            cli::Arg::Long("source") => {
                source = Some(PathBuf::from(cli::string(&mut parser, USAGE)))
            }
            cli::Arg::Long("target") => {
                target = Some(PathBuf::from(cli::string(&mut parser, USAGE)))
            }
            cli::Arg::Long("clip") => clip = Some(cli::string(&mut parser, USAGE)),
            cli::Arg::Long("map") => map = Some(PathBuf::from(cli::string(&mut parser, USAGE))),
            cli::Arg::Long("ground") => {
                let ground = cli::string(&mut parser, USAGE);
                if ground != "flat" {
                    cli::fail(format!("unknown ground {ground:?} (flat)"), USAGE);
                }
            }
            cli::Arg::Long("no-contacts") => contacts = false,
            cli::Arg::Long("stretch-legs") => stretch_legs = cli::value(&mut parser, USAGE),
            cli::Arg::Long("json") => {}
            other => cli::unexpected(other, USAGE),
        }
    }
    let (Some(source), Some(target)) = (source, target) else {
        cli::fail("--source and --target are required", USAGE);
    };
    Args {
        source,
        clip,
        target,
        map,
        contacts,
        stretch_legs,
    }
}

/// The source's skeleton, rest pose and clip: a BVH file, or a glTF character's animation.
fn read_source(args: &Args) -> Result<(Skeleton, SkeletonPose, PoseClip), String> {
    let motion =
        read_source_motion(&args.source, args.clip.as_deref()).map_err(|e| e.to_string())?;
    Ok((motion.skeleton, motion.rest, motion.clip))
}

/// The character with the joints of `legs` (each chain's joints after its first) moved `factor`
/// times as far from their parents: bones, rest pose, inverse binds and the skin's bind
/// positions (skinned at the stretched rest pose) all follow.
fn stretch(
    character: &GltfCharacter,
    legs: &[Vec<usize>],
    factor: f64,
) -> (Skeleton, SkeletonPose, SkinnedMesh) {
    let skeleton = &character.skeleton;
    let mut rest = character.rest.clone();
    for chain in legs {
        for &j in chain.iter().skip(1) {
            rest.local[j].translation *= factor;
        }
    }
    // Skin the bind shape at the stretched rest: each vertex by its joints' motion from the
    // original rest to the stretched one.
    let (before, after) = (
        skeleton.global_transforms(&character.rest),
        skeleton.global_transforms(&rest),
    );
    let skinning: Vec<DAffine3> = skeleton
        .skinning_matrices(&character.rest)
        .iter()
        .zip(before.iter().zip(&after))
        .map(|(s, (b, a))| *a * b.inverse() * *s)
        .collect();
    let mut mesh = character.mesh.clone();
    for (p, (ji, jw)) in mesh.positions.iter_mut().zip(
        character
            .mesh
            .joint_indices
            .iter()
            .zip(&character.mesh.joint_weights),
    ) {
        let bind = p.as_dvec3();
        let sum: f32 = jw.iter().sum();
        let moved: DVec3 = ji
            .iter()
            .zip(jw)
            .filter(|(_, w)| **w > 0.0)
            .map(|(&j, &w)| skinning[j as usize].transform_point3(bind) * f64::from(w / sum))
            .sum();
        *p = moved.as_vec3();
    }
    let joints = skeleton
        .joints()
        .iter()
        .zip(&after)
        .map(|(j, g)| Joint {
            inverse_bind: g.inverse(),
            ..j.clone()
        })
        .collect();
    (
        Skeleton::new(joints).expect("the same hierarchy"),
        rest,
        mesh,
    )
}

fn main() {
    let args = args();
    let (source, source_rest, clip) = read_source(&args).unwrap_or_else(|e| {
        eprintln!("{}: {e}", args.source.display());
        std::process::exit(1);
    });
    let target = GltfCharacter::read(&args.target).unwrap_or_else(|e| {
        eprintln!("{}: {e}", args.target.display());
        std::process::exit(1);
    });
    let map_of = |skeleton: &Skeleton, rest: &SkeletonPose| match &args.map {
        Some(path) => {
            let text = std::fs::read_to_string(path).unwrap_or_else(|e| {
                eprintln!("{}: {e}", path.display());
                std::process::exit(1);
            });
            SkeletonMap::from_ron(&text, (&source, &source_rest), (skeleton, rest))
        }
        None => SkeletonMap::humanoid((&source, &source_rest), (skeleton, rest)),
    };
    let first_map = map_of(&target.skeleton, &target.rest).unwrap_or_else(|e| {
        eprintln!("map: {e}");
        std::process::exit(1);
    });
    let (skeleton, rest, mesh) = if args.stretch_legs != 1.0 {
        let legs: Vec<Vec<usize>> = first_map
            .chains
            .iter()
            .filter(|c| first_map.feet.iter().any(|f| c.target.last() == Some(&f.1)))
            .map(|c| c.target.clone())
            .collect();
        stretch(&target, &legs, args.stretch_legs)
    } else {
        (
            target.skeleton.clone(),
            target.rest.clone(),
            target.mesh.clone(),
        )
    };
    let model = Arc::new(
        bevy_wii_deform::pose::SkinnedModel::new(
            skeleton.clone(),
            &mesh,
            &rest,
            ModelSettings::default(),
        )
        .unwrap_or_else(|e| {
            eprintln!("target model: {e}");
            std::process::exit(1);
        }),
    );
    let map = map_of(&skeleton, &rest).expect("mapped once already");
    let frames: Vec<SkeletonPose> = clip.keys().iter().map(|k| k.pose.clone()).collect();
    let run = |contacts: bool| {
        let settings = RetargetSettings {
            contacts,
            ..RetargetSettings::default()
        };
        let retargeter = Retargeter::new(
            (&source, &source_rest),
            model.clone(),
            &rest,
            map.clone(),
            settings,
        )
        .unwrap_or_else(|e| {
            eprintln!("retarget: {e}");
            std::process::exit(1);
        });
        let ground: GroundPlane = retargeter.rest_ground();
        let started = Instant::now();
        let baked = retargeter.bake(&clip, &ground).unwrap_or_else(|e| {
            eprintln!("bake: {e}");
            std::process::exit(1);
        });
        let ms = started.elapsed().as_secs_f64() * 1e3 / frames.len().max(1) as f64;
        let poses: Vec<SkeletonPose> = baked.clip.keys().iter().map(|k| k.pose.clone()).collect();
        let quality = retargeter.quality(&frames, &poses, &baked.source_contacts, &ground);
        // The same frames streamed one at a time (the live path), a frame's wall time each.
        let mut live = retargeter.live();
        let mut live_ms: Vec<f64> = clip
            .keys()
            .iter()
            .filter_map(|key| {
                let started = Instant::now();
                live.frame(&key.pose, f64::from(key.time), &ground).ok()?;
                Some(started.elapsed().as_secs_f64() * 1e3)
            })
            .collect();
        live_ms.sort_by(f64::total_cmp);
        let live_ms = live_ms.get(live_ms.len() / 2).copied().unwrap_or(f64::NAN);
        (ms, live_ms, baked, quality)
    };
    let (ms, live_ms, baked, quality) = run(args.contacts);
    let (_, _, _, bare) = run(false);
    let report = serde_json::json!({
        "source": args.source.display().to_string(),
        "target": args.target.display().to_string(),
        "target_joints": skeleton.len(),
        "stretch_legs": args.stretch_legs,
        "contacts": args.contacts,
        "joints_mapped": map.joints_mapped(),
        "roles_mapped": map.roles_mapped(),
        "unmapped": map.unmapped.iter().map(|&j| skeleton.joints()[j].name.clone()).collect::<Vec<_>>(),
        "frames": frames.len(),
        "bake_ms_per_frame": ms,
        "live_ms_per_frame_median": live_ms,
        "failed_solves": baked.failed_solves,
        "source_planted_share": baked.source_contacts.planted_share(),
        "source_ground_speed": baked.source_contacts.treadmill.length(),
        "foot_slide_max": quality.foot_slide_max,
        "penetration_max": quality.penetration_max,
        "limb_direction_error_deg_p95": quality.limb_direction_error_deg_p95,
        "bone_length_error_max": quality.bone_length_error_max,
        "foot_slide_max_without_contacts": bare.foot_slide_max,
        "penetration_max_without_contacts": bare.penetration_max,
    });
    println!("{report}");
}
