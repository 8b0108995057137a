//! `--clip PATH`: a clip made for another skeleton — a BVH file, or another glTF character's
//! animation — retargeted onto the character by the library's `RetargetPlugin` (feet kept
//! planted and on the ground) and played by the character's own `AnimationPlayer`, looping.
//! The HUD says how the retarget went.

use bevy::prelude::*;
use bevy_wii_deform::prelude::*;

use super::Args;
use super::scene::Character;

/// Retargets `--clip` onto the character and plays it.
pub struct ClipFromFilePlugin;

impl Plugin for ClipFromFilePlugin {
    fn build(&self, app: &mut App) {
        app.add_plugins(RetargetPlugin)
            .add_systems(Update, (ask_for_the_clip, play_the_clip));
    }
}

/// The character, once poseable, before its retarget is asked.
type NotYetAsked = (With<Character>, With<PosedSkeleton>, Without<Retarget>);

/// Puts the `--clip` retarget on the character once it is poseable.
fn ask_for_the_clip(
    mut commands: Commands,
    args: Res<Args>,
    character: Query<Entity, NotYetAsked>,
) {
    let Some(clip) = &args.clip else {
        return;
    };
    for entity in &character {
        let mut retarget = Retarget::new(&clip.source);
        retarget.animation = clip.animation.clone();
        retarget.map = clip.map.clone();
        commands.entity(entity).insert(retarget);
    }
}

/// Plays a landed retarget on the character's `AnimationPlayer`, looping; the pose plugin then
/// stops holding its own pose over the clip (a drag still poses it on top, until released).
fn play_the_clip(
    mut ready: MessageReader<RetargetReady>,
    mut characters: Query<&mut Poseable, With<Character>>,
    children: Query<&Children>,
    mut players: Query<(Entity, &mut AnimationPlayer)>,
    mut graphs: ResMut<Assets<AnimationGraph>>,
    mut commands: Commands,
) {
    for message in ready.read() {
        let Ok(mut poseable) = characters.get_mut(message.entity) else {
            continue;
        };
        let mut below =
            std::iter::once(message.entity).chain(children.iter_descendants(message.entity));
        let Some(player) = below.find(|e| players.contains(*e)) else {
            warn!("--clip: the character has no AnimationPlayer to play the clip");
            continue;
        };
        let (graph, node) = AnimationGraph::from_clip(message.clip.clone());
        commands
            .entity(player)
            .insert(AnimationGraphHandle(graphs.add(graph)));
        if let Ok((_, mut player)) = players.get_mut(player) {
            player.stop_all().play(node).repeat();
        }
        poseable.hold_pose = false;
    }
}

/// The HUD's line about the `--clip` retarget (`None` without one).
pub fn clip_line(args: &Args, status: Option<&RetargetStatus>) -> Option<String> {
    let clip = args.clip.as_ref()?;
    let name = clip.source.display();
    Some(match status {
        None => format!("clip {name}: waiting for the character"),
        Some(s) => match s.phase {
            RetargetPhase::Waiting | RetargetPhase::Baking => format!("clip {name}: retargeting…"),
            RetargetPhase::Ready => format!(
                "clip {name}: {} frames{}{}",
                s.frames,
                if s.unmapped.is_empty() {
                    String::new()
                } else {
                    format!(", {} joints unmapped", s.unmapped.len())
                },
                if s.failed_solves > 0 {
                    format!(", {} frames kept unsolved", s.failed_solves)
                } else {
                    String::new()
                }
            ),
            RetargetPhase::Failed => format!(
                "clip {name}: {}",
                s.error
                    .as_ref()
                    .map_or("failed".into(), ToString::to_string)
            ),
        },
    })
}
