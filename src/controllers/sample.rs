//! What every driver hands to fusion: calibrated sensor samples in one body frame, the
//! controller kinds, and the few buttons the controls need.

use glam::DVec3;

use super::fusion::ImuSample;
use super::motion::GRAVITY;

/// The controller families the crate reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ControllerKind {
    /// Nintendo Wii Remote (Plus, or with a MotionPlus attached).
    #[default]
    WiiRemote,
    /// Sony DualSense (PlayStation 5).
    DualSense,
    /// Sony DualSense Edge: the DualSense's reports, another product id.
    DualSenseEdge,
    /// Sony DualShock 4 (both revisions, and the USB wireless adaptor).
    DualShock4,
    /// Nintendo Switch Pro Controller.
    SwitchPro,
    /// Nintendo Joy-Con (L), on its own.
    JoyConLeft,
    /// Nintendo Joy-Con (R), on its own.
    JoyConRight,
}

impl ControllerKind {
    /// Every kind, Wii Remote first.
    pub const ALL: [ControllerKind; 7] = [
        ControllerKind::WiiRemote,
        ControllerKind::DualSense,
        ControllerKind::DualSenseEdge,
        ControllerKind::DualShock4,
        ControllerKind::SwitchPro,
        ControllerKind::JoyConLeft,
        ControllerKind::JoyConRight,
    ];

    /// The name used on command lines and in JSON (`wiimote`, `dualsense`, `ds4`, …).
    pub fn name(self) -> &'static str {
        match self {
            ControllerKind::WiiRemote => "wiimote",
            ControllerKind::DualSense => "dualsense",
            ControllerKind::DualSenseEdge => "dualsense-edge",
            ControllerKind::DualShock4 => "ds4",
            ControllerKind::SwitchPro => "switch-pro",
            ControllerKind::JoyConLeft => "joycon-l",
            ControllerKind::JoyConRight => "joycon-r",
        }
    }

    /// Parses [`ControllerKind::name`]; `joycon` is an alias of `joycon-r`.
    pub fn from_name(name: &str) -> Option<Self> {
        if name == "joycon" {
            return Some(ControllerKind::JoyConRight);
        }
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The kind a USB/Bluetooth vendor and product id belong to.
    pub fn from_ids(vendor: u16, product: u16) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|k| k.vendor_id() == vendor && k.product_ids().contains(&product))
    }

    /// USB/Bluetooth vendor id.
    pub fn vendor_id(self) -> u16 {
        match self {
            ControllerKind::DualSense
            | ControllerKind::DualSenseEdge
            | ControllerKind::DualShock4 => 0x054C,
            _ => 0x057E,
        }
    }

    /// The product ids this kind answers to.
    pub fn product_ids(self) -> &'static [u16] {
        match self {
            ControllerKind::WiiRemote => &[0x0306, 0x0330],
            ControllerKind::DualSense => &[0x0CE6],
            ControllerKind::DualSenseEdge => &[0x0DF2],
            // v1, v2, and Sony's USB wireless adaptor.
            ControllerKind::DualShock4 => &[0x05C4, 0x09CC, 0x0BA0],
            ControllerKind::SwitchPro => &[0x2009],
            ControllerKind::JoyConLeft => &[0x2006],
            ControllerKind::JoyConRight => &[0x2007],
        }
    }

    /// Whether the controller has an IR camera that sees a sensor bar (only the Wii Remote).
    pub fn has_ir_camera(self) -> bool {
        self == ControllerKind::WiiRemote
    }

    /// A product name for people.
    pub fn label(self) -> &'static str {
        match self {
            ControllerKind::WiiRemote => "Wii Remote",
            ControllerKind::DualSense => "DualSense",
            ControllerKind::DualSenseEdge => "DualSense Edge",
            ControllerKind::DualShock4 => "DualShock 4",
            ControllerKind::SwitchPro => "Switch Pro Controller",
            ControllerKind::JoyConLeft => "Joy-Con (L)",
            ControllerKind::JoyConRight => "Joy-Con (R)",
        }
    }
}

impl std::fmt::Display for ControllerKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.label())
    }
}

/// One calibrated sensor sample.
///
/// **Body frame** (every device): the Wii Remote's frame of `docs/PROTOCOL.md` §5.3,
/// right-handed — **+X the controller's left**, **+Y toward the player** (its back),
/// **+Z out of its top face** (the face with the buttons). A pad lying flat on a table reads
/// `accel_mps2 ≈ (0, 0, +9.81)`. Rates are right-hand-rule rates about those axes. Each
/// driver documents how its native axes map onto this frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionSample {
    /// Angular velocity, rad/s, bias *not* removed (fusion estimates it).
    pub gyro_rps: DVec3,
    /// Specific force (what an accelerometer reads: "up" at rest), m/s².
    pub accel_mps2: DVec3,
    /// The device's own sensor clock, seconds (wrapping as the device's counter wraps), when
    /// the report carries one.
    pub device_time_s: Option<f64>,
}

impl MotionSample {
    /// The sample in the units the orientation filters take (deg/s, g), stamped `dt`
    /// seconds after the previous one.
    pub fn to_imu(&self, timestamp_us: u64, dt: f64) -> ImuSample {
        ImuSample {
            timestamp_us,
            dt,
            gyro_dps: Some(self.gyro_rps * (180.0 / std::f64::consts::PI)),
            gyro_fast: [false; 3],
            accel_g: self.accel_mps2 / GRAVITY,
        }
    }

    /// Whether every component is finite.
    pub fn is_finite(&self) -> bool {
        self.gyro_rps.is_finite() && self.accel_mps2.is_finite()
    }
}

/// The buttons the controls use, named by role, plus the device's own button bits.
///
/// Roles, per device (chosen so the paper's one-handed use carries over): **clutch** — hold
/// to turn the handle (Wii B trigger, R2 / R1 on Sony pads, ZR / R on the Switch; ZL / L on a
/// left Joy-Con); **grab** — press to grab what the pointer is on (Wii A, Cross, A / B);
/// **recentre** (Wii Home, the PS button, Home / Capture); **calibrate** — rest the
/// controller and re-estimate the gyro bias (Wii 1, Triangle, X / Up). The d-pad and the
/// two small buttons move the handle as on the Wii Remote: **up/down/left/right** (the
/// d-pad), **plus/minus** (Wii +/−, Options/Create, +/−). A left Joy-Con's arrows are its face
/// buttons (grab, calibrate) and a right Joy-Con has no d-pad.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct PadButtons {
    /// Hold to turn the handle.
    pub clutch: bool,
    /// Grab what the pointer is on.
    pub grab: bool,
    /// Recentre the orientation and the pointer.
    pub recentre: bool,
    /// Restart the gyro bias estimate.
    pub calibrate: bool,
    /// D-pad up.
    pub up: bool,
    /// D-pad down.
    pub down: bool,
    /// D-pad left.
    pub left: bool,
    /// D-pad right.
    pub right: bool,
    /// Plus (moves the handle away).
    pub plus: bool,
    /// Minus (moves the handle closer).
    pub minus: bool,
    /// The device's button bits as they sit in its report (documented per protocol).
    pub raw: u32,
}
