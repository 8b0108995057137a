//! Humanoid joint roles found by name, for the limits preset ([`JointLimits::humanoid`]) and the
//! mirror ([`crate::pose::rig::mirror`]).
//!
//! A joint's name is reduced to a *base* before matching: lower case; the exporter prefixes
//! `mixamorig:` / `mixamorig_` (Mixamo), `def-` / `org-` / `mch-` (Blender Rigify), `j_bip_c_`,
//! `j_bip_l_`, `j_bip_r_` (VRM 0.x) removed; a trailing instance number (`_012`, `.001`)
//! removed; the side (`left`/`right` anywhere, `.l`/`.r`, `_l`/`_r`, `l_`/`r_`, `-l`/`-r`)
//! removed and remembered. Then the base is looked up:
//!
//! | role | Mixamo | Rigify | VRM (0.x nodes / 1.0 bones) | limit |
//! |---|---|---|---|---|
//! | spine | `Spine`, `Spine1`, `Spine2` | `spine.001`–`spine.003` | `Spine`, `Chest`, `UpperChest` | cone 30° × 30°, twist ±30° |
//! | neck | `Neck` | `spine.004`, `neck` | `Neck` | cone 45° × 45°, twist ±60° |
//! | head | `Head` | `spine.006`, `head` | `Head` | cone 40° × 40°, twist ±45° |
//! | clavicle | `Shoulder` | `shoulder` | `Shoulder` | cone 20° × 20°, twist ±10° (an upper arm when the side has no other) |
//! | upper arm | `Arm` | `upper_arm` | `UpperArm` | cone 100° × 100°, twist ±90° |
//! | elbow | `ForeArm` | `forearm` | `LowerArm` | hinge −5°…150° (flexes forward) |
//! | wrist | `Hand` | `hand` | `Hand` | cone 70° × 45°, twist ±30° |
//! | hip | `UpLeg` | `thigh` | `UpperLeg` | cone 90° × 60°, twist ±45° |
//! | knee | `Leg` | `shin` | `LowerLeg` | hinge −5°…150° (flexes backward) |
//! | ankle | `Foot` | `foot` | `Foot` | cone 40° × 30°, twist ±20° |
//! | toes | `ToeBase` | `toe` | `ToeBase`, `Toes` | cone 40° × 10°, twist ±5° |
//!
//! Other sources' names are found too: motion-capture libraries (CMU's BVH `LowerBack`,
//! `Neck1`, and its ASF-converted `lfemur`, `ltibia`, `lhumerus`, `lradius`, `thorax`,
//! `lowerneck`; Bandai Namco / Truebones `UpperArm_L`, `LowerLeg_L`, `Toes_L`), Unreal's
//! mannequin (`spine_01`…`spine_05`, `neck_01`, `clavicle_l`, `upperarm_l`, `lowerarm_l`,
//! `thigh_l`, `calf_l`, `ball_l`), 3ds Max Biped (`Bip01 L Thigh`, `Bip01 L Calf`,
//! `Bip01 L Toe0`, `Bip01 L Clavicle`), Daz Genesis (`lThighBend`, `lShin`, `lShldrBend`,
//! `lForearmBend`, `abdomenLower`, `chestUpper`, `neckLower`). A pelvis or hips joint has no
//! role: retargeting finds the hips as the joint the two thighs hang from.
//!
//! Rigs named after joints rather than bones are recognised too: `elbow`, `wrist`, `hip`,
//! `knee`, `ankle`. The hips (root) and fingers are left free. Hinge axes are found from the rest pose: the
//! character's up is +Y and forward +Z of the skeleton root's parent space (glTF's axes), an
//! elbow turns about `bone × forward` and a knee about `forward × bone`, so a flexed elbow
//! brings the hand forward and a flexed knee takes the foot back, whatever each exporter's bone
//! roll.

/// A humanoid joint's role.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HumanoidRole {
    /// A spine or chest segment.
    Spine,
    /// The neck.
    Neck,
    /// The head.
    Head,
    /// A clavicle.
    Clavicle,
    /// An upper arm (shoulder joint).
    UpperArm,
    /// A forearm (elbow joint).
    Elbow,
    /// A hand (wrist joint).
    Wrist,
    /// A thigh (hip joint).
    Hip,
    /// A shin (knee joint).
    Knee,
    /// A foot (ankle joint).
    Ankle,
    /// The toes.
    Toes,
}

/// Which side of the body a name says its joint is on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Side {
    /// The character's left.
    Left,
    /// The character's right.
    Right,
}

/// A joint name split into its base (lower case, no exporter prefix, no instance number, no
/// side) and its side, if it names one.
pub fn split_name(name: &str) -> (String, Option<Side>) {
    let mut s = name.to_lowercase();
    for prefix in [
        "mixamorig:",
        "mixamorig_",
        "def-",
        "org-",
        "mch-",
        "j_bip_c_",
        "bip01 ",
        "bip001 ",
        "bip01_",
        "bip001_",
    ] {
        if let Some(rest) = s.strip_prefix(prefix) {
            s = rest.to_string();
        }
    }
    let mut side = None;
    for (prefix, which) in [("j_bip_l_", Side::Left), ("j_bip_r_", Side::Right)] {
        if let Some(rest) = s.strip_prefix(prefix) {
            s = rest.to_string();
            side = Some(which);
        }
    }
    s = strip_instance_number(&s);
    if side.is_none() {
        (s, side) = strip_side(&s);
    }
    (strip_instance_number(&s), side)
}

/// Removes a trailing `_012` / `.001` / `-3` (an exporter's instance number). Rigify's
/// `spine.001` keeps its number: only numbers after another number-free part go, and `spine`
/// segments are matched with them.
fn strip_instance_number(s: &str) -> String {
    let trimmed = s.trim_end_matches(|c: char| c.is_ascii_digit());
    if trimmed.len() < s.len()
        && let Some(base) = trimmed.strip_suffix(['_', '.', '-'])
        && !base.is_empty()
        && !base.starts_with("spine")
    {
        return base.to_string();
    }
    s.to_string()
}

fn strip_side(s: &str) -> (String, Option<Side>) {
    for (word, side) in [("left", Side::Left), ("right", Side::Right)] {
        if let Some(at) = s.find(word) {
            let mut out = s.to_string();
            out.replace_range(at..at + word.len(), "");
            let out = out.trim_matches(|c| c == '_' || c == '.' || c == '-' || c == ' ');
            return (out.to_string(), Some(side));
        }
    }
    for (l, r) in [(".l", ".r"), ("_l", "_r"), ("-l", "-r"), (" l", " r")] {
        if let Some(base) = s.strip_suffix(l) {
            return (base.to_string(), Some(Side::Left));
        }
        if let Some(base) = s.strip_suffix(r) {
            return (base.to_string(), Some(Side::Right));
        }
    }
    for (l, r) in [("l_", "r_"), ("l.", "r."), ("l-", "r-"), ("l ", "r ")] {
        if let Some(base) = s.strip_prefix(l) {
            return (base.to_string(), Some(Side::Left));
        }
        if let Some(base) = s.strip_prefix(r) {
            return (base.to_string(), Some(Side::Right));
        }
    }
    (s.to_string(), None)
}

/// The humanoid role of a joint name, if it has one (see the module's table).
pub fn humanoid_role(name: &str) -> Option<HumanoidRole> {
    humanoid_role_and_side(name).map(|(role, _)| role)
}

/// The humanoid role of a joint name and the side it is on. Besides the table's names, a
/// side written as a bare `l`/`r` before the rest of the name is recognised where the rest is
/// a known limb (`lfemur`, `rHand`, `lThighBend`: the ASF-converted CMU skeletons, Daz).
pub fn humanoid_role_and_side(name: &str) -> Option<(HumanoidRole, Option<Side>)> {
    let (base, side) = split_name(name);
    let base = base.replace(['_', '.', '-', ' '], "");
    if let Some(role) = role_of_base(&base, side.is_some()) {
        return Some((role, side));
    }
    if side.is_none() {
        for (prefix, side) in [("l", Side::Left), ("r", Side::Right)] {
            if let Some(rest) = base.strip_prefix(prefix)
                && let Some(role) = role_of_base(rest, true)
                && !matches!(
                    role,
                    HumanoidRole::Spine | HumanoidRole::Neck | HumanoidRole::Head
                )
            {
                return Some((role, Some(side)));
            }
        }
    }
    None
}

fn role_of_base(base: &str, sided: bool) -> Option<HumanoidRole> {
    use HumanoidRole::*;
    let role = match base {
        "spine" | "spine1" | "spine2" | "spine3" | "spine001" | "spine002" | "spine003"
        | "spine01" | "spine02" | "spine03" | "spine04" | "spine05" | "chest" | "upperchest"
        | "lowerback" | "upperback" | "thorax" | "abdomen" | "abdomenlower" | "abdomenupper"
        | "chestlower" | "chestupper" | "torso" => Spine,
        "neck" | "spine004" | "neck1" | "neck01" | "neck02" | "lowerneck" | "upperneck"
        | "necklower" | "neckupper" => Neck,
        "head" | "spine006" => Head,
        "shoulder" | "clavicle" | "collar" if sided => Clavicle,
        "arm" | "upperarm" | "uparm" | "humerus" | "shldr" | "shldrbend" if sided => UpperArm,
        "forearm" | "lowerarm" | "elbow" | "radius" | "forearmbend" if sided => Elbow,
        "hand" | "wrist" if sided => Wrist,
        "upleg" | "thigh" | "upperleg" | "hip" | "femur" | "thighbend" if sided => Hip,
        "leg" | "shin" | "lowerleg" | "calf" | "knee" | "tibia" if sided => Knee,
        "foot" | "ankle" if sided => Ankle,
        "toebase" | "toe" | "toes" | "toe0" | "ball" if sided => Toes,
        _ => return None,
    };
    Some(role)
}
