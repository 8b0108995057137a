//! How the emulated remote answers the host: output reports, register reads and writes, the
//! MotionPlus activation sequence, status reports and acknowledgements (`PROTOCOL.md`).

use std::collections::VecDeque;

use super::{EmulatedRemote, Variant};
use crate::controllers::wiimote::protocol::{AddressSpace, OutputReport};

/// Where the MotionPlus is in its activation sequence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum MpPhase {
    Absent,
    Inactive,
    Activating { until_us: u64, mode: u8, fail: bool },
    Active { mode: u8 },
    Deactivating { until_us: u64 },
}

/// Size of the remote's EEPROM address space.
pub(super) const EEPROM_SIZE: usize = 0x1700;

/// A memory read being answered, one data report (≤ 16 bytes) per chunk.
pub(super) struct PendingRead {
    pub(super) chunks: VecDeque<Vec<u8>>,
}

impl EmulatedRemote {
    pub(super) fn compute_ext_line(&self) -> bool {
        let nunchuk = self.controls.with(|s| s.nunchuk.is_some());
        match self.mp {
            MpPhase::Active { .. } => true,
            MpPhase::Activating { .. } | MpPhase::Deactivating { .. } => false,
            _ => nunchuk || self.config.variant == Variant::BalanceBoard,
        }
    }

    pub(super) fn status_report(&self) -> Vec<u8> {
        let b = self.buttons().to_bytes();
        let lf = (self.ext_line as u8) << 1 | (self.leds << 4) | (self.config.battery < 0x20) as u8;
        vec![0x20, b[0], b[1], lf, 0, 0, self.config.battery]
    }

    pub(super) fn ack(&mut self, report: u8, error: u8) {
        let b = self.buttons().to_bytes();
        let at = self.now_us + 1000;
        self.push(at, vec![0x22, b[0], b[1], report, error]);
    }

    pub(super) fn update_ext_line(&mut self, send_status: bool) {
        let line = self.compute_ext_line();
        if line != self.ext_line {
            self.ext_line = line;
            if send_status {
                let at = self.now_us + 500;
                let r = self.status_report();
                self.push(at, r);
                self.reporting_enabled = false;
            }
        }
    }

    /// Advances state machines (activation timers, hot-plug) to `now_us`.
    pub(super) fn advance_state(&mut self) {
        let gen_now = self.controls.with(|s| s.generation);
        if gen_now != self.generation {
            self.generation = gen_now;
            self.power_on();
        }
        // Hot-plug of the external MotionPlus and Nunchuk.
        let mp_plugged = self.has_mp_hardware();
        if mp_plugged != self.was_mp_plugged {
            self.was_mp_plugged = mp_plugged;
            if !mp_plugged {
                self.mp = MpPhase::Absent;
                self.update_ext_line(true);
            } else {
                self.mp = MpPhase::Inactive; // no status report: poll to find it
            }
        }
        let nunchuk = self.controls.with(|s| s.nunchuk.is_some());
        if nunchuk != self.was_nunchuk {
            self.was_nunchuk = nunchuk;
            if !nunchuk {
                self.ext_initialized = false;
            }
            // While the MotionPlus is active, pass-through hot-plug shows only in E4 bit0.
            if !matches!(self.mp, MpPhase::Active { .. }) {
                self.update_ext_line(true);
            }
        }
        match self.mp {
            MpPhase::Activating {
                until_us,
                mode,
                fail,
            } if self.now_us >= until_us => {
                if fail {
                    self.mp = MpPhase::Inactive;
                } else {
                    self.mp = MpPhase::Active { mode };
                    self.mp_last_mode = mode;
                    self.garbage_left = self.config.garbage_frames_after_activation;
                }
                let quiet = self.config.drop_activation_status;
                self.update_ext_line(!quiet);
            }
            MpPhase::Deactivating { until_us } if self.now_us >= until_us => {
                self.mp = MpPhase::Inactive;
                self.ext_initialized = false;
                self.update_ext_line(true);
            }
            _ => {}
        }
    }

    pub(super) fn mp_id(&self, active: bool) -> [u8; 6] {
        let first = if self.config.variant == Variant::Plus {
            0x01
        } else {
            0x00
        };
        match self.mp {
            MpPhase::Active { mode } if active => [first, 0, 0xA4, 0x20, mode, 0x05],
            _ => [first, 0, 0xA6, 0x20, self.mp_last_mode, 0x05],
        }
    }

    /// Register read: Ok(bytes) or Err(error code).
    pub(super) fn read_registers(
        &mut self,
        slave: u8,
        offset: u8,
        size: usize,
    ) -> Result<Vec<u8>, u8> {
        let slave = slave & 0xFE;
        let mut regs = [0u8; 256];
        match slave {
            0xA0 => return Err(8),
            0xA6 => {
                if self.mp != MpPhase::Inactive {
                    return Err(7);
                }
                regs = self.mp_regs;
                regs[0x20..0x40].copy_from_slice(&self.unit.mp_cal.encode());
                regs[0xFA..].copy_from_slice(&self.mp_id(false));
            }
            0xA4 => match self.mp {
                MpPhase::Active { .. } => {
                    regs = self.mp_regs;
                    regs[0x20..0x40].copy_from_slice(&self.unit.mp_cal.encode());
                    regs[0xFA..].copy_from_slice(&self.mp_id(true));
                }
                MpPhase::Activating { .. } | MpPhase::Deactivating { .. } => return Err(7),
                _ => {
                    if self.config.variant == Variant::BalanceBoard {
                        regs[0xFA..].copy_from_slice(&[0, 0, 0xA4, 0x20, 0x04, 0x02]);
                    } else if self.controls.with(|s| s.nunchuk.is_some()) {
                        if self.ext_initialized {
                            regs[0xFA..].copy_from_slice(&[0, 0, 0xA4, 0x20, 0, 0]);
                        } else {
                            regs[0xFA..].copy_from_slice(&[0xFF; 6]);
                        }
                    } else {
                        return Err(7);
                    }
                }
            },
            0xB0 if !self.config.camera => return Err(7),
            0xB0 => regs.copy_from_slice(&self.camera_regs),
            0xA2 => {}
            _ => return Err(7),
        }
        let start = offset as usize;
        if start + size > 256 {
            return Err(8);
        }
        Ok(regs[start..start + size].to_vec())
    }

    pub(super) fn write_registers(&mut self, slave: u8, offset: u8, data: &[u8]) -> u8 {
        let slave = slave & 0xFE;
        let v = data.first().copied().unwrap_or(0);
        match slave {
            0xA0 => 8,
            0xA6 => {
                if self.mp != MpPhase::Inactive {
                    return 7;
                }
                if offset == 0xFE && data.len() == 1 && matches!(v, 0x04 | 0x05 | 0x07) {
                    let fail = self.activations_failed < self.config.activation_fails_n_times;
                    if fail {
                        self.activations_failed += 1;
                    }
                    self.mp = MpPhase::Activating {
                        until_us: self.now_us + self.config.activation_ms as u64 * 1000,
                        mode: v,
                        fail,
                    };
                    let quiet = self.config.drop_activation_status;
                    self.update_ext_line(!quiet);
                } else {
                    for (i, b) in data.iter().enumerate() {
                        if let Some(r) = self.mp_regs.get_mut(offset as usize + i) {
                            *r = *b;
                        }
                    }
                }
                0
            }
            0xA4 => match self.mp {
                MpPhase::Active { .. } => {
                    if (offset == 0xF0 && v == 0x55)
                        || (offset == 0xFE && !matches!(v, 0x04 | 0x05 | 0x07))
                    {
                        self.mp = MpPhase::Deactivating {
                            until_us: self.now_us + self.config.activation_ms as u64 * 1000,
                        };
                        self.update_ext_line(true);
                    } else if offset == 0xFE {
                        self.mp = MpPhase::Active { mode: v };
                        self.mp_last_mode = v;
                    }
                    0
                }
                MpPhase::Activating { .. } | MpPhase::Deactivating { .. } => 7,
                _ => {
                    let present = self.controls.with(|s| s.nunchuk.is_some())
                        || self.config.variant == Variant::BalanceBoard;
                    if !present {
                        return 7;
                    }
                    if offset == 0xF0 && v == 0x55 {
                        self.ext_initialized = true;
                    }
                    0
                }
            },
            0xB0 if !self.config.camera => 7,
            0xB0 => {
                for (i, b) in data.iter().enumerate() {
                    if let Some(r) = self.camera_regs.get_mut(offset as usize + i) {
                        *r = *b;
                    }
                }
                0
            }
            0xA2 => 0,
            _ => 7,
        }
    }

    pub(super) fn handle_output(&mut self, report: &[u8]) {
        if let Some(&f) = report.get(1)
            && report[0] != 0x18
        {
            self.rumble = f & 1 != 0;
        }
        let decoded = OutputReport::decode(report);
        let id = report.first().copied().unwrap_or(0);
        if self.config.error2_acks && id != 0x10 && self.rng.uniform() < 0.2 {
            self.ack(id, 2);
        }
        let (ack_requested, error) = match decoded {
            Err(_) => {
                if id == 0x16 || id == 0x17 {
                    self.ack(id, 6);
                }
                return;
            }
            Ok(OutputReport::Rumble { .. }) => return,
            Ok(OutputReport::Leds { leds, ack, .. }) => {
                self.leds = leds;
                (ack, 0)
            }
            Ok(OutputReport::ReportMode {
                mode,
                continuous,
                ack,
                ..
            }) => {
                if !matches!(mode, 0x30..=0x3F) {
                    return; // invalid mode: whole report ignored
                }
                self.mode = mode;
                self.continuous = continuous;
                self.reporting_enabled = true;
                (ack, 0)
            }
            Ok(OutputReport::Flag { ack, .. }) => (ack, 0),
            Ok(OutputReport::StatusRequest { .. }) => {
                let at = self.now_us + 1000;
                let r = self.status_report();
                self.push(at, r);
                self.reporting_enabled = false;
                return;
            }
            Ok(OutputReport::WriteMemory {
                space,
                address,
                data,
                ..
            }) => {
                self.write_memory(space, address, &data);
                return;
            }
            Ok(OutputReport::ReadMemory {
                space,
                address,
                size,
                ..
            }) => {
                self.read_memory(space, address, size);
                return;
            }
            Ok(OutputReport::SpeakerData) => return,
        };
        if ack_requested || self.config.always_ack {
            self.ack(id, error);
        }
    }

    /// A memory write (report 0x16): EEPROM or registers, acknowledged with its error code;
    /// an empty or over-long write is ignored without an ack, as the hardware does.
    fn write_memory(&mut self, space: AddressSpace, address: u32, data: &[u8]) {
        if data.is_empty() || data.len() > 16 {
            return;
        }
        let error = match space {
            AddressSpace::Eeprom => {
                let a = address as usize;
                if a + data.len() > EEPROM_SIZE {
                    8
                } else {
                    self.eeprom[a..a + data.len()].copy_from_slice(data);
                    0
                }
            }
            AddressSpace::Registers => {
                self.write_registers((address >> 16) as u8, address as u8, data)
            }
        };
        self.ack(0x16, error);
    }

    /// A memory read (report 0x17): its answer queued as 0x21 reports of up to 16 bytes, or one
    /// with the error code; a read while another is answered is refused (error 4).
    fn read_memory(&mut self, space: AddressSpace, address: u32, size: u16) {
        if size == 0 {
            return;
        }
        if self.read.is_some() {
            self.ack(0x17, 4);
            return;
        }
        let size = size as usize;
        let result = match space {
            AddressSpace::Eeprom => {
                let a = address as usize;
                if a + size > EEPROM_SIZE {
                    Err(8)
                } else {
                    Ok(self.eeprom[a..a + size].to_vec())
                }
            }
            AddressSpace::Registers => {
                self.read_registers((address >> 16) as u8, address as u8, size)
            }
        };
        let b = self.buttons().to_bytes();
        let lo = address as u16;
        let mut chunks = VecDeque::new();
        match result {
            Err(code) => {
                let mut r = vec![0x21, b[0], b[1], 0xF0 | code];
                r.extend_from_slice(&lo.to_be_bytes());
                r.resize(22, 0);
                chunks.push_back(r);
            }
            Ok(data) => {
                for (i, c) in data.chunks(16).enumerate() {
                    let mut r = vec![0x21, b[0], b[1], ((c.len() as u8 - 1) << 4)];
                    r.extend_from_slice(&(lo.wrapping_add(16 * i as u16)).to_be_bytes());
                    r.extend_from_slice(c);
                    r.resize(22, 0);
                    chunks.push_back(r);
                }
            }
        }
        self.read = Some(PendingRead { chunks });
    }
}
