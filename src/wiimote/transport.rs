//! The byte transport under a session: hidapi for real remotes, or the emulator.

/// Transport failures.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TransportError {
    /// The remote is gone (powered off, out of range, unpaired).
    #[error("the remote disconnected")]
    Disconnected,
    /// Another I/O error (message from the OS / hidapi).
    #[error("I/O error: {0}")]
    Io(String),
}

/// Raw HID report I/O with a clock. One transport per remote, used from one I/O thread.
pub trait Transport: Send {
    /// Writes one output report (report id first). Returns bytes written.
    fn write(&mut self, report: &[u8]) -> Result<usize, TransportError>;
    /// Reads one input report into `buf` (report id first), waiting at most `timeout_ms`.
    /// Returns 0 on timeout.
    fn read_timeout(&mut self, buf: &mut [u8], timeout_ms: u32) -> Result<usize, TransportError>;
    /// Microseconds on this transport's clock (wall clock for hardware, virtual for the
    /// emulator), used to timestamp samples.
    fn now_us(&self) -> u64;
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn write(&mut self, report: &[u8]) -> Result<usize, TransportError> {
        (**self).write(report)
    }
    fn read_timeout(&mut self, buf: &mut [u8], timeout_ms: u32) -> Result<usize, TransportError> {
        (**self).read_timeout(buf, timeout_ms)
    }
    fn now_us(&self) -> u64 {
        (**self).now_us()
    }
}

#[cfg(feature = "hidapi")]
pub use hid::*;

#[cfg(feature = "hidapi")]
mod hid {
    use std::time::Instant;

    use super::{Transport, TransportError};
    use crate::wiimote::protocol::{
        NAME_ORIGINAL, NAME_PLUS, PRODUCT_ID_ORIGINAL, PRODUCT_ID_PLUS, VENDOR_ID,
    };

    /// A remote found by [`discover`].
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct DeviceInfo {
        /// OS path (e.g. `/dev/hidraw3`).
        pub path: String,
        /// USB/Bluetooth product id.
        pub product_id: u16,
        /// Product string, if readable.
        pub product: Option<String>,
        /// Serial (Bluetooth address), if readable.
        pub serial: Option<String>,
    }

    /// Why no usable remote was found, with what to do about it.
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub enum Diagnosis {
        /// `/dev/hidrawN` is not readable by this user: needs a udev rule.
        Permission {
            /// Device node.
            node: String,
        },
        /// The in-kernel `hid-wiimote` driver is bound and will fight us.
        KernelDriverBound {
            /// Device node.
            node: String,
        },
    }

    impl std::fmt::Display for Diagnosis {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            match self {
                Diagnosis::Permission { node } => write!(
                    f,
                    "{node} is not accessible. Add /etc/udev/rules.d/60-wiimote.rules with\n  \
                     KERNEL==\"hidraw*\", KERNELS==\"0005:057E:0306.*\", TAG+=\"uaccess\"\n  \
                     KERNEL==\"hidraw*\", KERNELS==\"0005:057E:0330.*\", TAG+=\"uaccess\"\n\
                     (or MODE=\"0660\", GROUP=\"input\"), then `sudo udevadm control --reload` and reconnect the remote."
                ),
                Diagnosis::KernelDriverBound { node } => write!(
                    f,
                    "the hid-wiimote kernel driver is bound to {node} and talks to the remote too. \
                     Unbind it (as root): echo <HID id, e.g. 0005:057E:0306.0007> > /sys/bus/hid/drivers/wiimote/unbind \
                     && echo <same id> > /sys/bus/hid/drivers/hid-generic/bind; or blacklist it: \
                     echo 'blacklist hid_wiimote' > /etc/modprobe.d/wiimote.conf"
                ),
            }
        }
    }

    /// Lists Wii Remotes (by VID/PID and by product string, for clones).
    pub fn discover() -> Result<Vec<DeviceInfo>, TransportError> {
        let api = hidapi::HidApi::new().map_err(|e| TransportError::Io(e.to_string()))?;
        let mut out: Vec<DeviceInfo> = Vec::new();
        for d in api.device_list() {
            let product = d.product_string().map(str::to_string);
            let by_name = matches!(product.as_deref(), Some(NAME_ORIGINAL) | Some(NAME_PLUS));
            let by_id = d.vendor_id() == VENDOR_ID
                && (d.product_id() == PRODUCT_ID_ORIGINAL || d.product_id() == PRODUCT_ID_PLUS);
            let path = d.path().to_string_lossy().into_owned();
            if (by_name || by_id) && !out.iter().any(|o| o.path == path) {
                out.push(DeviceInfo {
                    path,
                    product_id: d.product_id(),
                    product,
                    serial: d.serial_number().map(str::to_string),
                });
            }
        }
        Ok(out)
    }

    /// Linux: explains why hidraw remotes are unusable (permissions, kernel driver).
    pub fn diagnose_linux() -> Vec<Diagnosis> {
        let mut out = Vec::new();
        let Ok(dir) = std::fs::read_dir("/sys/class/hidraw") else {
            return out;
        };
        for entry in dir.flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            let uevent =
                std::fs::read_to_string(entry.path().join("device/uevent")).unwrap_or_default();
            let is_wiimote = uevent.contains("057E")
                && (uevent.contains("0306") || uevent.contains("0330"))
                || uevent.contains("RVL-CNT");
            if !is_wiimote {
                continue;
            }
            let node = format!("/dev/{name}");
            if let Ok(driver) = std::fs::read_link(entry.path().join("device/driver"))
                && driver.to_string_lossy().ends_with("wiimote")
            {
                out.push(Diagnosis::KernelDriverBound { node: node.clone() });
            }
            if std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .open(&node)
                .is_err()
            {
                out.push(Diagnosis::Permission { node });
            }
        }
        out
    }

    /// A remote opened through hidapi.
    pub struct HidTransport {
        device: hidapi::HidDevice,
        epoch: Instant,
    }

    impl HidTransport {
        /// Opens the device at `path`.
        pub fn open(path: &str) -> Result<Self, TransportError> {
            let api = hidapi::HidApi::new().map_err(|e| TransportError::Io(e.to_string()))?;
            let cpath =
                std::ffi::CString::new(path).map_err(|e| TransportError::Io(e.to_string()))?;
            let device = api
                .open_path(&cpath)
                .map_err(|e| TransportError::Io(e.to_string()))?;
            Ok(Self {
                device,
                epoch: Instant::now(),
            })
        }
    }

    impl Transport for HidTransport {
        fn write(&mut self, report: &[u8]) -> Result<usize, TransportError> {
            self.device
                .write(report)
                .map_err(|_| TransportError::Disconnected)
        }
        fn read_timeout(
            &mut self,
            buf: &mut [u8],
            timeout_ms: u32,
        ) -> Result<usize, TransportError> {
            self.device
                .read_timeout(buf, timeout_ms.min(i32::MAX as u32) as i32)
                .map_err(|_| TransportError::Disconnected)
        }
        fn now_us(&self) -> u64 {
            self.epoch.elapsed().as_micros() as u64
        }
    }
}
