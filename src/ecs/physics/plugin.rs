//! Systems of [`DeformPhysicsPlugin`]: collider rebuilds after settled solves, the colliders
//! marked [`GroundMesh`] as the scene's ground, capsules on posed bones.

use avian3d::prelude::*;
use bevy::prelude::*;
use crossbeam_channel::TryRecvError;

use super::builder::ColliderBuilder;
use super::{
    BoneCollider, ColliderBuild, ColliderGround, DeformCollider, DeformColliderStatus,
    PosedColliders,
};
use crate::ecs::deform::mesh_positions;
use crate::ecs::{
    DeformPhase, DeformStatus, DeformSystems, GroundMesh, PosedSkeleton, SceneGround,
};
use crate::pose::fit_bone_capsules;

/// The systems of [`DeformPhysicsPlugin`].
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DeformPhysicsSystems {
    /// `PreUpdate`: [`SceneGround`] from the [`GroundMesh`] colliders.
    Ground,
    /// `Update`, after [`DeformSystems::Writeback`]: start collider builds for settled bends,
    /// swap in the finished ones.
    Rebuild,
}

/// Rebuilds the colliders of bent [`DeformCollider`] meshes and casts the ground on
/// [`GroundMesh`] colliders (module docs of [`crate::ecs::physics`]). Add it with Avian's
/// `PhysicsPlugins` and the deform or pose plugins.
#[derive(Debug, Clone, Copy, Default)]
pub struct DeformPhysicsPlugin;

impl Plugin for DeformPhysicsPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<ColliderBuilder>()
            .register_type::<DeformCollider>()
            .register_type::<DeformColliderStatus>()
            .register_type::<PosedColliders>()
            .register_type::<BoneCollider>()
            .configure_sets(
                Update,
                DeformPhysicsSystems::Rebuild.after(DeformSystems::Writeback),
            )
            .add_systems(
                PreUpdate,
                collect_collider_ground.in_set(DeformPhysicsSystems::Ground),
            )
            .add_systems(
                Update,
                (
                    start_collider_builds,
                    swap_built_colliders,
                    fit_posed_colliders,
                )
                    .chain()
                    .in_set(DeformPhysicsSystems::Rebuild),
            );
    }
}

/// A [`DeformCollider`] mesh: what its collider build reads (its collider now is the one the
/// build replaces).
type BentMesh<'a> = (
    Entity,
    &'a DeformCollider,
    &'a DeformStatus,
    &'a DeformColliderStatus,
    &'a Mesh3d,
    Option<&'a Collider>,
);

/// Starts a background collider build for every [`DeformCollider`] mesh whose last solve has
/// settled (its status idle) and is newer than its collider.
fn start_collider_builds(
    mut commands: Commands,
    mut builder: ResMut<ColliderBuilder>,
    meshes: Res<Assets<Mesh>>,
    bent: Query<BentMesh, Without<ColliderBuild>>,
) {
    for (entity, wanted, status, built, mesh, previous) in &bent {
        let settled = status.phase == DeformPhase::Idle && status.error.is_none();
        if !settled || status.solves == 0 || status.solves == built.built_from_solve {
            continue;
        }
        let Some(mesh) = meshes.get(&mesh.0) else {
            continue;
        };
        let Some(positions) = mesh_positions(mesh) else {
            continue;
        };
        // The index buffer goes as it is (one copy); the builder thread makes the triangles.
        let indices = mesh.indices().cloned();
        let result = builder.build(wanted.shape, positions, indices, previous.cloned());
        commands.entity(entity).try_insert(ColliderBuild {
            result,
            solve: status.solves,
        });
    }
}

/// Swaps finished colliders in (the old one stays when a build failed). The old shape is
/// taken out of the entity and handed to the builder thread, which then holds its last
/// reference and frees it (a large triangle mesh takes milliseconds to free). The collider is
/// replaced in place: Avian's systems pick up a changed collider (its scale, mass properties
/// and bounding box) in the next physics step.
fn swap_built_colliders(
    mut commands: Commands,
    mut builder: ResMut<ColliderBuilder>,
    mut builds: Query<(
        Entity,
        &mut ColliderBuild,
        &mut DeformColliderStatus,
        Option<&mut Collider>,
    )>,
) {
    for (entity, build, mut status, current) in &mut builds {
        let result = match build.result.try_recv() {
            Ok(result) => result,
            Err(TryRecvError::Empty) => continue,
            // The builder thread is gone (it panicked): the old collider stays.
            Err(TryRecvError::Disconnected) => Err("the collider builder stopped".into()),
        };
        status.built_from_solve = build.solve;
        let mut entity = commands.entity(entity);
        entity.try_remove::<ColliderBuild>();
        match result {
            Ok(collider) => {
                match current {
                    Some(mut current) => builder.free(std::mem::replace(&mut *current, collider)),
                    None => {
                        entity.try_insert(collider);
                    }
                }
                status.rebuilds += 1;
                status.error = None;
            }
            Err(reason) => status.error = Some(reason),
        }
    }
}

/// A character with [`PosedColliders`] that was (re)prepared or changed its settings.
type CharactersToFit = Or<(Added<PosedSkeleton>, Changed<PosedColliders>)>;

/// Gives the bones of a newly posed [`PosedColliders`] character their capsules (replacing
/// any it had).
fn fit_posed_colliders(
    mut commands: Commands,
    characters: Query<(Entity, &PosedSkeleton, &PosedColliders), CharactersToFit>,
    bones: Query<(Entity, &BoneCollider)>,
) {
    for (character, posed, settings) in &characters {
        for (bone, of) in &bones {
            if of.character == character {
                commands.entity(bone).try_despawn();
            }
        }
        for capsule in fit_bone_capsules(&posed.model, f64::from(settings.min_weight)) {
            let Some(&joint) = posed.joints.get(capsule.joint) else {
                continue;
            };
            commands.spawn((
                BoneCollider { character },
                RigidBody::Kinematic,
                Collider::capsule_endpoints(
                    capsule.radius as f32,
                    capsule.a.as_vec3(),
                    capsule.b.as_vec3(),
                ),
                Transform::default(),
                ChildOf(joint),
            ));
        }
    }
}

/// A [`GroundMesh`] collider moved, was added or got another shape.
type ChangedGroundCollider = (
    With<GroundMesh>,
    Or<(
        Changed<Collider>,
        Changed<GlobalTransform>,
        Added<ColliderAabb>,
    )>,
);

/// Keeps [`SceneGround`] on the [`GroundMesh`] colliders while there are any.
fn collect_collider_ground(
    mut commands: Commands,
    colliders: Query<(&Collider, &GlobalTransform, &ColliderAabb), With<GroundMesh>>,
    changed: Query<(), ChangedGroundCollider>,
    mut removed: RemovedComponents<Collider>,
    mut ours: Local<bool>,
) {
    let any_removed = removed.read().count() > 0;
    if changed.is_empty() && !any_removed {
        return;
    }
    let snapshot: Vec<_> = colliders
        .iter()
        .map(|(c, t, aabb)| {
            let (_, rotation, translation) = t.to_scale_rotation_translation();
            (c.clone(), translation, rotation, *aabb)
        })
        .collect();
    if snapshot.is_empty() {
        if std::mem::take(&mut *ours) {
            // The meshes are the ground again (GroundPlugin rebuilds it).
            commands.remove_resource::<SceneGround>();
        }
        return;
    }
    *ours = true;
    commands.insert_resource(SceneGround::custom(ColliderGround::new(snapshot)));
}
