//! What is emulated: the remote's variant, its sensor error model and the emulator's settings.

use crate::controllers::emulation::EmulatorClock;

/// Which remote is emulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// RVL-CNT-01 (PID 0x0306), optionally with an external MotionPlus dongle.
    Original {
        /// A MotionPlus is plugged in at power-on.
        motion_plus: bool,
    },
    /// RVL-CNT-01-TR (PID 0x0330) with built-in MotionPlus.
    Plus,
    /// A Balance Board (same PID as the original; must be rejected by the session).
    BalanceBoard,
}

/// Sensor error model (defaults from `PROTOCOL.md` §13.3).
#[derive(Debug, Clone, PartialEq)]
pub struct SensorModel {
    /// Gyro white noise σ per sample at 100 Hz, deg/s.
    pub gyro_noise_dps: f64,
    /// Turn-on bias σ, deg/s.
    pub gyro_turn_on_bias_dps: f64,
    /// Bias random walk, deg/s/√s.
    pub gyro_bias_walk: f64,
    /// Temperature drift reached after 10 minutes (deg/s, random sign per axis).
    pub gyro_temperature_drift_dps: f64,
    /// Cross-axis sensitivity, uniform in ± this (off-diagonal terms).
    pub gyro_misalignment: f64,
    /// Calibration-block scale error (uniform ±).
    pub gyro_block_scale_error: f64,
    /// Calibration-block zero error σ in 16-bit counts.
    pub gyro_block_zero_error: f64,
    /// Slow-mode sensitivities in 14-bit counts per deg/s (yaw, roll, pitch); `None` = draw.
    pub gyro_slow_counts_per_dps: Option<[f64; 3]>,
    /// Mirrored gyro polarity (with a matching calibration block).
    pub reversed: bool,
    /// Accelerometer noise σ, g.
    pub accel_noise_g: f64,
    /// Accelerometer cross-axis sensitivity, uniform in ± this (off-diagonal terms).
    pub accel_misalignment: f64,
    /// Accelerometer scale error, uniform in ± this (diagonal terms).
    pub accel_scale_error: f64,
}

impl Default for SensorModel {
    fn default() -> Self {
        Self {
            gyro_noise_dps: 0.15,
            gyro_turn_on_bias_dps: 0.5,
            gyro_bias_walk: 0.01,
            gyro_temperature_drift_dps: 1.0,
            gyro_misalignment: 0.01,
            gyro_block_scale_error: 0.02,
            gyro_block_zero_error: 40.0,
            gyro_slow_counts_per_dps: Some([15.64, 20.03, 14.33]),
            reversed: false,
            accel_noise_g: 0.0033,
            accel_misalignment: 0.02,
            accel_scale_error: 0.02,
        }
    }
}

impl SensorModel {
    /// A perfect sensor (no noise, bias, misalignment or calibration error).
    pub fn ideal() -> Self {
        Self {
            gyro_noise_dps: 0.0,
            gyro_turn_on_bias_dps: 0.0,
            gyro_bias_walk: 0.0,
            gyro_temperature_drift_dps: 0.0,
            gyro_misalignment: 0.0,
            gyro_block_scale_error: 0.0,
            gyro_block_zero_error: 0.0,
            accel_noise_g: 0.0,
            accel_misalignment: 0.0,
            accel_scale_error: 0.0,
            ..Self::default()
        }
    }
}

/// Emulator configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct EmulatorConfig {
    /// Which remote.
    pub variant: Variant,
    /// Seed: same seed → byte-identical stream.
    pub seed: u64,
    /// Data report rate (100 Hz on PCs, 200 Hz in sniff mode).
    pub report_rate_hz: f64,
    /// Delivery jitter, ± microseconds (uniform).
    pub jitter_us: u32,
    /// Probability of dropping a data report.
    pub drop_probability: f64,
    /// Deliver `k` reports at once every `k` ticks (Bluetooth burst), if set.
    pub burst: Option<u32>,
    /// MotionPlus activation/deactivation time, ms.
    pub activation_ms: u32,
    /// Send no status reports on MotionPlus activation (Dolphin PR #8626 case).
    pub drop_activation_status: bool,
    /// Garbage MotionPlus frames after activation.
    pub garbage_frames_after_activation: u32,
    /// The first N activations silently fail.
    pub activation_fails_n_times: u32,
    /// Pad input reports to 22 bytes like Windows.
    pub windows_padding: bool,
    /// Ack every output report, even without the ack bit.
    pub always_ack: bool,
    /// -TR quirk: extra unsolicited `22 .. RR 02` acks.
    pub error2_acks: bool,
    /// Deliver reports in real time (sleep until due) instead of instantly.
    pub realtime: bool,
    /// Deliver reports as this clock reaches them (takes precedence over `realtime`); the
    /// emulator's time starts at the clock's time when the remote is opened.
    pub clock: Option<EmulatorClock>,
    /// Battery level byte.
    pub battery: u8,
    /// Sensor error model.
    pub sensors: SensorModel,
    /// Emulates a remote the OS lists but refuses to open (the manager reports this as a
    /// [`crate::controllers::wiimote::RemoteProblem`] and retries); `None` opens normally.
    pub open_error: Option<crate::controllers::diagnosis::OpenErrorKind>,
    /// The IR camera (I2C device 0xB0) answers register writes and reads (`PROTOCOL.md` §17);
    /// `false` emulates a unit whose camera does not answer (error 7, as for an absent device).
    pub camera: bool,
    /// What the camera sees: a sensor bar and where the remote stands (`None`: no bar, every
    /// dot slot empty). Dots are projected from the emulated pose into report 0x36/0x37
    /// (basic) or 0x33 (extended) once the camera's mode register is set.
    pub sensor_bar: Option<EmulatedBar>,
}

/// The sensor bar an emulated remote's camera sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmulatedBar {
    /// The bar and screen (room frame of the emulated motion).
    pub setup: crate::controllers::wiimote::ir::PointerSetup,
    /// Where the remote is, relative to the nominal standing point.
    pub position: glam::DVec3,
    /// Gaussian pixel noise per coordinate before quantisation (σ, pixels).
    pub noise_px: f64,
}

impl Default for EmulatorConfig {
    fn default() -> Self {
        Self {
            variant: Variant::Plus,
            seed: 1,
            report_rate_hz: 100.0,
            jitter_us: 2000,
            drop_probability: 0.0,
            burst: None,
            activation_ms: 50,
            drop_activation_status: false,
            garbage_frames_after_activation: 2,
            activation_fails_n_times: 0,
            windows_padding: false,
            always_ack: false,
            error2_acks: false,
            realtime: false,
            clock: None,
            battery: 0x68,
            sensors: SensorModel::default(),
            open_error: None,
            camera: true,
            sensor_bar: None,
        }
    }
}
