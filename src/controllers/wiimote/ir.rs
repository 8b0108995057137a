//! The Wii Remote's IR camera: its initialisation, the dot formats of its reports, a camera
//! model that projects a sensor bar, and the pointer (dots → where the remote points on the
//! screen, roll-compensated with the accelerometer). Specification: `docs/PROTOCOL.md` §17.
//!
//! Conventions (the project's, shared by the decoder, the camera model and the pointer):
//! image coordinates are pixels of the 1024 × 768 image as seen looking out of the remote's IR
//! window with its top face up — x grows to the remote's right, y grows downwards. The remote's
//! body axes are those of `PROTOCOL.md` §5.3: +X its left side, +Y its back, +Z its top; it
//! points along −Y. The room frame of the camera model has +Z up and the screen in the plane
//! `y = −distance` in front of a remote at the origin.
//!
//! ```
//! use bevy_wii_deform::controllers::wiimote::ir::*;
//! use glam::{DQuat, DVec3};
//!
//! let setup = PointerSetup::default();
//! // A remote held still 2 m in front of the screen's centre, aimed at its centre.
//! let dots = IrCamera::default().project(&setup, DVec3::ZERO, DQuat::IDENTITY);
//! let gravity = DVec3::Z; // lying level: the accelerometer reads +1 g on +Z
//! let at = setup.pointed_at(&dots, gravity).unwrap();
//! assert!((at - glam::DVec2::splat(0.5)).length() < 5e-3);
//! ```

use glam::{DQuat, DVec2, DVec3};

use super::protocol::{InputReport, ProtocolError};

pub use crate::controllers::session::inputs::{IrDot, IrDots, IrSensitivity};

/// Width of the camera's reported image, pixels.
pub const IR_WIDTH: u16 = 1024;
/// Height of the camera's reported image, pixels.
pub const IR_HEIGHT: u16 = 768;
/// The camera's register block (I2C device 0xB0) in the remote's register space.
pub const IR_REGISTER_BASE: u32 = 0xB0_0000;
/// The control register: 0x08 before and after configuring.
pub const IR_CONTROL_REGISTER: u32 = 0xB0_0030;
/// Sensitivity block 1 (9 bytes).
pub const IR_SENSITIVITY_1: u32 = 0xB0_0000;
/// Sensitivity block 2 (2 bytes).
pub const IR_SENSITIVITY_2: u32 = 0xB0_001A;
/// The mode register (1 basic, 3 extended, 5 full).
pub const IR_MODE_REGISTER: u32 = 0xB0_0033;

/// Why IR bytes could not be decoded, or a camera set-up is unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IrError {
    /// A block of IR bytes of the wrong length for its mode.
    #[error("{mode:?} IR data is {expected} bytes, got {got}")]
    WrongLength {
        /// The mode the bytes were read as.
        mode: IrMode,
        /// Bytes that mode needs.
        expected: usize,
        /// Bytes given.
        got: usize,
    },
    /// A report that is not 0x37 read as one.
    #[error("report 0x{0:02X} is not a buttons + accelerometer + IR + extension report (0x37)")]
    NotReport37(u8),
    /// A dot outside the 1024 × 768 image (a corrupt report: the camera never sends one).
    #[error("IR dot at ({x}, {y}) lies outside the 1024 × 768 image")]
    DotOutOfRange {
        /// Decoded x.
        x: u16,
        /// Decoded y.
        y: u16,
    },
    /// The sensor bar is not in view: fewer than two dots (the pointer needs both clusters).
    #[error("the sensor bar is not in view ({0} dot(s) seen)")]
    BarNotInView(usize),
    /// The report itself is malformed (truncated, …).
    #[error(transparent)]
    Protocol(#[from] ProtocolError),
    /// A set-up value that makes no geometry (zero or negative size or distance, NaN).
    #[error("invalid pointer set-up: {0}")]
    InvalidSetup(&'static str),
}

/// The camera's data formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum IrMode {
    /// 10 bytes, four dots of position only (reports 0x36, 0x37).
    Basic,
    /// 12 bytes, four dots with a size each (report 0x33).
    Extended,
    /// 36 bytes over two interleaved reports (0x3E/0x3F), nine bytes per dot.
    Full,
}

impl IrMode {
    /// The value written to the mode register.
    pub fn register_value(self) -> u8 {
        match self {
            IrMode::Basic => 1,
            IrMode::Extended => 3,
            IrMode::Full => 5,
        }
    }

    /// Bytes of IR data this mode fills.
    pub fn data_len(self) -> usize {
        match self {
            IrMode::Basic => 10,
            IrMode::Extended => 12,
            IrMode::Full => 36,
        }
    }
}

/// The camera's register bytes for `sensitivity`: block 1 (9 bytes at 0xB00000) and block 2
/// (2 bytes at 0xB0001A).
pub fn sensitivity_blocks(sensitivity: IrSensitivity) -> ([u8; 9], [u8; 2]) {
    // Bytes 6, 8 and block 2 set the gain and the brightness threshold.
    let (b6, b8, tail) = match sensitivity {
        IrSensitivity::Level1 => (0x64, 0xFE, [0xFD, 0x05]),
        IrSensitivity::Level2 => (0x96, 0xB4, [0xB3, 0x04]),
        IrSensitivity::Level3 => (0xAA, 0x64, [0x63, 0x03]),
        IrSensitivity::Level4 => (0xC8, 0x36, [0x35, 0x03]),
        IrSensitivity::Level5 => (0x72, 0x20, [0x1F, 0x03]),
        IrSensitivity::Max => return ([0, 0, 0, 0, 0, 0, 0x90, 0, 0x41], [0x40, 0x00]),
    };
    let first = if sensitivity == IrSensitivity::Level5 {
        0x07
    } else {
        0x02
    };
    ([first, 0, 0, 0x71, 0x01, 0, b6, 0, b8], tail)
}

/// One step of turning the camera on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum IrInitStep {
    /// Output report `report` (0x13 pixel clock, 0x1A logic) with its enable bit (0x04) set.
    Enable {
        /// The output report id.
        report: u8,
    },
    /// Write `bytes` to the camera's registers at `address` (report 0x16, register space).
    Write {
        /// 24-bit register address (0xB0xxxx).
        address: u32,
        /// The bytes.
        bytes: Vec<u8>,
    },
}

/// The camera's initialisation, in order: pixel clock, logic, control 0x08, the two
/// sensitivity blocks, the mode, control 0x08 again. After it the host selects a data report
/// that carries IR (0x37 with the MotionPlus: basic mode).
pub fn ir_init_sequence(mode: IrMode, sensitivity: IrSensitivity) -> Vec<IrInitStep> {
    let (block1, block2) = sensitivity_blocks(sensitivity);
    vec![
        IrInitStep::Enable { report: 0x13 },
        IrInitStep::Enable { report: 0x1A },
        IrInitStep::Write {
            address: IR_CONTROL_REGISTER,
            bytes: vec![0x08],
        },
        IrInitStep::Write {
            address: IR_SENSITIVITY_1,
            bytes: block1.to_vec(),
        },
        IrInitStep::Write {
            address: IR_SENSITIVITY_2,
            bytes: block2.to_vec(),
        },
        IrInitStep::Write {
            address: IR_MODE_REGISTER,
            bytes: vec![mode.register_value()],
        },
        IrInitStep::Write {
            address: IR_CONTROL_REGISTER,
            bytes: vec![0x08],
        },
    ]
}

fn checked(x: u16, y: u16, size: Option<u8>) -> Result<Option<IrDot>, IrError> {
    if x == 0x3FF && y == 0x3FF {
        return Ok(None); // an empty slot: all ones
    }
    if x >= IR_WIDTH || y >= IR_HEIGHT {
        return Err(IrError::DotOutOfRange { x, y });
    }
    Ok(Some(IrDot { x, y, size }))
}

fn expect_len(mode: IrMode, bytes: &[u8]) -> Result<(), IrError> {
    if bytes.len() != mode.data_len() {
        return Err(IrError::WrongLength {
            mode,
            expected: mode.data_len(),
            got: bytes.len(),
        });
    }
    Ok(())
}

/// Decodes basic-mode IR data (10 bytes): two groups of five bytes, each two dots —
/// `X1 Y1 HI X2 Y2` with `HI = y1[9:8]·64 + x1[9:8]·16 + y2[9:8]·4 + x2[9:8]`.
pub fn decode_basic(bytes: &[u8]) -> Result<IrDots, IrError> {
    expect_len(IrMode::Basic, bytes)?;
    let mut dots = [None; 4];
    for (pair, chunk) in bytes.chunks_exact(5).enumerate() {
        let hi = chunk[2] as u16;
        let x1 = chunk[0] as u16 | ((hi >> 4) & 3) << 8;
        let y1 = chunk[1] as u16 | ((hi >> 6) & 3) << 8;
        let x2 = chunk[3] as u16 | (hi & 3) << 8;
        let y2 = chunk[4] as u16 | ((hi >> 2) & 3) << 8;
        dots[pair * 2] = checked(x1, y1, None)?;
        dots[pair * 2 + 1] = checked(x2, y2, None)?;
    }
    Ok(dots)
}

/// Encodes dots as basic-mode IR data (the emulator's side of [`decode_basic`]).
pub fn encode_basic(dots: &IrDots) -> [u8; 10] {
    let mut out = [0u8; 10];
    let raw = |d: &Option<IrDot>| d.map_or((0x3FF, 0x3FF), |d| (d.x & 0x3FF, d.y & 0x3FF));
    for pair in 0..2 {
        let (x1, y1) = raw(&dots[pair * 2]);
        let (x2, y2) = raw(&dots[pair * 2 + 1]);
        let o = &mut out[pair * 5..pair * 5 + 5];
        o[0] = x1 as u8;
        o[1] = y1 as u8;
        o[2] = ((y1 >> 8) << 6 | (x1 >> 8) << 4 | (y2 >> 8) << 2 | (x2 >> 8)) as u8;
        o[3] = x2 as u8;
        o[4] = y2 as u8;
    }
    out
}

/// Decodes extended-mode IR data (12 bytes): three bytes per dot, `X Y HI` with
/// `HI = y[9:8]·64 + x[9:8]·16 + size`.
pub fn decode_extended(bytes: &[u8]) -> Result<IrDots, IrError> {
    expect_len(IrMode::Extended, bytes)?;
    let mut dots = [None; 4];
    for (k, chunk) in bytes.chunks_exact(3).enumerate() {
        let hi = chunk[2] as u16;
        let x = chunk[0] as u16 | ((hi >> 4) & 3) << 8;
        let y = chunk[1] as u16 | ((hi >> 6) & 3) << 8;
        dots[k] = checked(x, y, Some((hi & 0x0F) as u8))?;
    }
    Ok(dots)
}

/// Encodes dots as extended-mode IR data (sizes default to 4).
pub fn encode_extended(dots: &IrDots) -> [u8; 12] {
    let mut out = [0xFFu8; 12];
    for (k, dot) in dots.iter().enumerate() {
        if let Some(d) = dot {
            let (x, y) = (d.x & 0x3FF, d.y & 0x3FF);
            out[k * 3] = x as u8;
            out[k * 3 + 1] = y as u8;
            out[k * 3 + 2] = ((y >> 8) << 6 | (x >> 8) << 4) as u8 | (d.size.unwrap_or(4) & 0x0F);
        }
    }
    out
}

/// Decodes full-mode IR data (36 bytes, the two halves of reports 0x3E and 0x3F joined): nine
/// bytes per dot, the extended three followed by a bounding box and an intensity, which are
/// not used here.
pub fn decode_full(bytes: &[u8]) -> Result<IrDots, IrError> {
    expect_len(IrMode::Full, bytes)?;
    let mut dots = [None; 4];
    for (k, chunk) in bytes.chunks_exact(9).enumerate() {
        let hi = chunk[2] as u16;
        let x = chunk[0] as u16 | ((hi >> 4) & 3) << 8;
        let y = chunk[1] as u16 | ((hi >> 6) & 3) << 8;
        dots[k] = checked(x, y, Some((hi & 0x0F) as u8))?;
    }
    Ok(dots)
}

/// Data report 0x37: buttons, the accelerometer, basic IR and six extension bytes (the
/// MotionPlus data while it is active).
#[derive(Debug, Clone, PartialEq)]
pub struct Report37 {
    /// The core buttons (`protocol::Buttons` bits).
    pub buttons: u16,
    /// Raw 10-bit accelerometer counts, X Y Z.
    pub accel: [u16; 3],
    /// The decoded dots.
    pub dots: IrDots,
    /// The extension bytes (MotionPlus: `protocol::MotionPlusSample`'s six bytes).
    pub extension: [u8; 6],
}

impl Report37 {
    /// Decodes a whole input report, id first (22 bytes: `37 BB BB AX AY AZ I×10 E×6`);
    /// buttons and accelerometer as [`InputReport::decode`] reads them.
    pub fn parse(report: &[u8]) -> Result<Report37, IrError> {
        match report.first() {
            Some(0x37) => {}
            other => return Err(IrError::NotReport37(other.copied().unwrap_or(0))),
        }
        let InputReport::Data {
            buttons,
            accel: Some(accel),
            extension: Some(extension),
            ..
        } = InputReport::decode(report)?
        else {
            return Err(IrError::NotReport37(0x37));
        };
        Ok(Report37 {
            buttons: buttons.0,
            accel: accel.0,
            dots: decode_basic(&report[6..16])?,
            extension,
        })
    }
}

/// Where the sensor bar sits relative to the screen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BarPlacement {
    /// On top of the screen (the bar's centre `gap` above the top edge).
    #[default]
    Above,
    /// Below the screen.
    Below,
}

/// The room: a screen, a sensor bar on it, and how far the player stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointerSetup {
    /// Screen width, metres.
    pub screen_width: f64,
    /// Screen height, metres.
    pub screen_height: f64,
    /// Distance between the clusters' centres, metres (the Wii's bar: 0.20).
    pub bar_width: f64,
    /// Above or below the screen.
    pub placement: BarPlacement,
    /// Gap between the screen's edge and the bar's centre, metres.
    pub gap: f64,
    /// Distance from the screen the player nominally stands at, metres (the camera model
    /// places the remote here; the pointer measures it from the dots' spacing).
    pub distance: f64,
}

impl Default for PointerSetup {
    /// A 42-inch 16:9 screen (0.93 × 0.52 m), the bar 3 cm above it, the player 2 m away.
    fn default() -> Self {
        Self {
            screen_width: 0.93,
            screen_height: 0.52,
            bar_width: 0.20,
            placement: BarPlacement::Above,
            gap: 0.03,
            distance: 2.0,
        }
    }
}

impl PointerSetup {
    /// Checks the geometry is usable.
    pub fn validate(&self) -> Result<(), IrError> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(self.screen_width) || !positive(self.screen_height) {
            return Err(IrError::InvalidSetup("the screen size must be positive"));
        }
        if !positive(self.bar_width) {
            return Err(IrError::InvalidSetup("the bar width must be positive"));
        }
        if !positive(self.distance) || !self.gap.is_finite() {
            return Err(IrError::InvalidSetup(
                "the distance must be positive and the gap finite",
            ));
        }
        Ok(())
    }

    /// Height of the bar's centre above the screen's centre, metres (negative below).
    pub fn bar_height(&self) -> f64 {
        let edge = self.screen_height / 2.0 + self.gap;
        match self.placement {
            BarPlacement::Above => edge,
            BarPlacement::Below => -edge,
        }
    }

    /// The two clusters in the room frame (+Z up, screen at `y = −distance`, +X to the left
    /// as the player faces the screen).
    pub fn clusters(&self) -> [DVec3; 2] {
        let centre = DVec3::new(0.0, -self.distance, self.bar_height());
        let half = DVec3::X * self.bar_width / 2.0;
        [centre + half, centre - half]
    }

    /// A point of the screen in the room frame, from normalised screen coordinates (0, 0) top
    /// left … (1, 1) bottom right, as the player sees it.
    pub fn screen_point(&self, at: DVec2) -> DVec3 {
        DVec3::new(
            -(at.x - 0.5) * self.screen_width,
            -self.distance,
            -(at.y - 0.5) * self.screen_height,
        )
    }

    /// Where the remote points on the screen, normalised (0, 0) top left … (1, 1) bottom right
    /// (outside that range when it points off the screen), from the two bar dots and the
    /// accelerometer's gravity reading (body frame, any scale: it gives the roll).
    ///
    /// Exact for a remote anywhere on the screen's central axis at any distance and
    /// orientation; off that axis the error grows with the offset (the Wii's own pointer makes
    /// the same assumption). The distance is measured from the dots' spacing.
    pub fn pointed_at(&self, dots: &IrDots, gravity: DVec3) -> Result<DVec2, IrError> {
        self.validate()?;
        let aim = self.aim(dots, gravity)?;
        // The aim ray from the remote (on the central axis, at the measured distance).
        let (origin, direction) = aim;
        if direction.y >= -1e-9 {
            return Err(IrError::BarNotInView(2)); // pointing away from the screen
        }
        let t = (-self.distance - origin.y) / direction.y;
        let hit = origin + direction * t;
        Ok(DVec2::new(
            0.5 - hit.x / self.screen_width,
            0.5 - hit.z / self.screen_height,
        ))
    }

    /// The remote's position (on the central axis) and pointing direction in the room frame,
    /// reconstructed from the dots and gravity (see [`PointerSetup::pointed_at`]).
    pub fn aim(&self, dots: &IrDots, gravity: DVec3) -> Result<(DVec3, DVec3), IrError> {
        let (da, db) = IrCamera::default().cluster_directions(dots)?;
        // Distance to the bar from the angle between the clusters.
        let angle = da.angle_between(db);
        if angle.is_nan() || angle <= 1e-6 {
            return Err(IrError::BarNotInView(1));
        }
        let range = self.bar_width / 2.0 / (angle / 2.0).tan();
        // The remote sits on the screen's axis: the bar's centre is at (0, −d, h) from it.
        let h = self.bar_height();
        let d = (range * range - h * h).max(1e-6).sqrt();
        let to_bar = DVec3::new(0.0, -d, h).normalize();
        // Roll from gravity: the rotation about the pointing axis (−Y) that levels the remote.
        let g = gravity.normalize_or_zero();
        if g == DVec3::ZERO {
            return Err(IrError::InvalidSetup("no gravity reading"));
        }
        // Level, the reading is +Z; rolled by φ about the pointing axis it is
        // (−cos θ sin φ, ·, cos θ cos φ) for a pitch θ.
        let roll = (-g.x).atan2(g.z);
        let unroll = DQuat::from_rotation_y(roll);
        let c = unroll * ((da + db) / 2.0).normalize();
        // Pitch about body X, then yaw about room Z, taking the camera's bar direction `c` to
        // the bar's room direction.
        let r = (c.y * c.y + c.z * c.z).sqrt();
        let alpha = c.z.atan2(c.y);
        let s = (to_bar.z / r).clamp(-1.0, 1.0);
        // Two pitches give that elevation; the remote faces the screen (c'.y < 0).
        let candidates = [s.asin() - alpha, std::f64::consts::PI - s.asin() - alpha];
        let pitch = candidates
            .into_iter()
            .find(|p| (DQuat::from_rotation_x(*p) * c).y < 0.0)
            .unwrap_or(candidates[0]);
        let pitched = DQuat::from_rotation_x(pitch) * c;
        let yaw = to_bar.y.atan2(to_bar.x) - pitched.y.atan2(pitched.x);
        let orientation = DQuat::from_rotation_z(yaw) * DQuat::from_rotation_x(pitch);
        let direction = orientation * DVec3::NEG_Y;
        // The remote stands `d` in front of the screen (the room frame puts the screen at
        // `y = −distance`, the nominal standing point at the origin).
        Ok((DVec3::new(0.0, d - self.distance, 0.0), direction))
    }
}

/// The orientation (body → room) of a remote at `position` pointing its −Y axis at `target`
/// (room frame, +Z up), rolled by `roll` radians about that axis (positive lifts its left
/// side): how an emulated remote is aimed at a spot of the screen
/// ([`PointerSetup::screen_point`]).
pub fn aimed_at(position: DVec3, target: DVec3, roll: f64) -> DQuat {
    let d = (target - position).normalize_or(DVec3::NEG_Y);
    // −Y turned by a pitch θ about X, then a yaw ψ about Z, is (sin ψ cos θ, −cos ψ cos θ,
    // −sin θ).
    let pitch = (-d.z).clamp(-1.0, 1.0).asin();
    let yaw = d.x.atan2(-d.y);
    DQuat::from_rotation_z(yaw) * DQuat::from_rotation_x(pitch) * DQuat::from_rotation_y(roll)
}

/// The IR camera: resolution 1024 × 768 and its field of view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IrCamera {
    /// Horizontal field of view, radians (WiiBrew: about 33°).
    pub fov_x: f64,
    /// Vertical field of view, radians (about 23°).
    pub fov_y: f64,
}

impl Default for IrCamera {
    fn default() -> Self {
        Self {
            fov_x: 33f64.to_radians(),
            fov_y: 23f64.to_radians(),
        }
    }
}

impl IrCamera {
    /// The body-frame rays to the bar's two clusters: the two dots farthest apart (stray
    /// reflections sit between or near them); a typed error with fewer than two dots or two
    /// dots on one pixel.
    pub fn cluster_directions(&self, dots: &IrDots) -> Result<(DVec3, DVec3), IrError> {
        let seen: Vec<DVec2> = dots.iter().flatten().map(IrDot::position).collect();
        if seen.len() < 2 {
            return Err(IrError::BarNotInView(seen.len()));
        }
        let (mut a, mut b) = (seen[0], seen[1]);
        for i in 0..seen.len() {
            for j in i + 1..seen.len() {
                if seen[i].distance_squared(seen[j]) > a.distance_squared(b) {
                    (a, b) = (seen[i], seen[j]);
                }
            }
        }
        if a == b {
            return Err(IrError::BarNotInView(1));
        }
        Ok((self.direction(a), self.direction(b)))
    }

    /// The body-frame unit direction from the remote to the sensor bar's centre (the mean of
    /// the two clusters' rays): what the heading reference of the orientation filter measures
    /// (`docs/PROTOCOL.md` §17.6).
    pub fn bar_direction(&self, dots: &IrDots) -> Result<DVec3, IrError> {
        let (a, b) = self.cluster_directions(dots)?;
        Ok((a + b).normalize())
    }

    /// The body-frame direction of the ray through pixel `p` (inverse of the projection).
    pub fn direction(&self, p: DVec2) -> DVec3 {
        let u = (p.x - IR_WIDTH as f64 / 2.0) / (IR_WIDTH as f64 / 2.0) * (self.fov_x / 2.0).tan();
        let v =
            (p.y - IR_HEIGHT as f64 / 2.0) / (IR_HEIGHT as f64 / 2.0) * (self.fov_y / 2.0).tan();
        // Right in the image = the remote's right = −X; down = −Z; forward = −Y.
        DVec3::new(-u, -1.0, -v).normalize()
    }

    /// Where a body-frame point projects in the image (pixels, not rounded), or `None` behind
    /// the camera or outside its view.
    pub fn project_body(&self, p: DVec3) -> Option<DVec2> {
        let forward = -p.y;
        if forward <= 1e-9 {
            return None;
        }
        let (u, v) = (-p.x / forward, -p.z / forward);
        let x = IR_WIDTH as f64 / 2.0 * (1.0 + u / (self.fov_x / 2.0).tan());
        let y = IR_HEIGHT as f64 / 2.0 * (1.0 + v / (self.fov_y / 2.0).tan());
        let inside = (0.0..IR_WIDTH as f64).contains(&x) && (0.0..IR_HEIGHT as f64).contains(&y);
        inside.then_some(DVec2::new(x, y))
    }

    /// The dots of the bar's two clusters seen by a remote at `position` (room frame, relative
    /// to the nominal standing point) turned by `orientation` (body → room), quantised to whole
    /// pixels; a cluster outside the view is lost (its slot empty).
    pub fn project(&self, setup: &PointerSetup, position: DVec3, orientation: DQuat) -> IrDots {
        self.project_with_noise(setup, position, orientation, &mut |_| 0.0)
    }

    /// As [`IrCamera::project`], with `noise(k)` pixels added to coordinate `k` (x0 y0 x1 y1)
    /// before quantising: pass a closure drawing from the camera's noise model.
    pub fn project_with_noise(
        &self,
        setup: &PointerSetup,
        position: DVec3,
        orientation: DQuat,
        noise: &mut dyn FnMut(usize) -> f64,
    ) -> IrDots {
        let mut dots = [None; 4];
        for (k, cluster) in setup.clusters().iter().enumerate() {
            let body = orientation.inverse() * (*cluster - position);
            dots[k] = self.project_body(body).and_then(|p| {
                let x = (p.x + noise(2 * k)).round();
                let y = (p.y + noise(2 * k + 1)).round();
                let inside =
                    (0.0..IR_WIDTH as f64).contains(&x) && (0.0..IR_HEIGHT as f64).contains(&y);
                inside.then_some(IrDot {
                    x: x as u16,
                    y: y as u16,
                    size: Some(4),
                })
            });
        }
        dots
    }
}
