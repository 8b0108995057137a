//! The byte transport under a session: hidapi for real controllers, or an emulator.

/// Transport failures.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TransportError {
    /// The remote is gone (powered off, out of range, unpaired).
    #[error("the remote disconnected")]
    Disconnected,
    /// Another I/O error (message from the OS / hidapi).
    #[error("I/O error: {0}")]
    Io(String),
    /// The device does not answer this request (e.g. feature reports on a Wii Remote).
    #[error("the device does not support {0}")]
    Unsupported(&'static str),
    /// The device node could not be opened.
    #[error("cannot open {node}: {kind:?}")]
    Open {
        /// Device node.
        node: String,
        /// Why.
        kind: crate::controllers::diagnosis::OpenErrorKind,
    },
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
    /// Reads feature report `buf[0]` into `buf` (report id first). Returns bytes read.
    /// Wii Remotes have none; Sony pads keep their calibration there.
    fn get_feature_report(&mut self, _buf: &mut [u8]) -> Result<usize, TransportError> {
        Err(TransportError::Unsupported("feature reports"))
    }
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
    fn get_feature_report(&mut self, buf: &mut [u8]) -> Result<usize, TransportError> {
        (**self).get_feature_report(buf)
    }
}

#[cfg(feature = "hidapi")]
pub use hid::*;

#[cfg(feature = "hidapi")]
mod hid {
    use web_time::Instant;

    use super::{Transport, TransportError};

    /// A remote opened through hidapi.
    pub struct HidTransport {
        device: hidapi::HidDevice,
        epoch: Instant,
    }

    impl HidTransport {
        /// Opens the device at `path`. A node that cannot be opened gives
        /// [`TransportError::Open`] with the OS's reason (hidapi's own error is only a message,
        /// so the node is probed first).
        pub fn open(path: &str) -> Result<Self, TransportError> {
            #[cfg(target_os = "linux")]
            if let Err(kind) = crate::controllers::diagnosis::probe_open(std::path::Path::new(path))
            {
                return Err(TransportError::Open {
                    node: path.to_string(),
                    kind,
                });
            }
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
        fn get_feature_report(&mut self, buf: &mut [u8]) -> Result<usize, TransportError> {
            self.device
                .get_feature_report(buf)
                .map_err(|e| TransportError::Io(e.to_string()))
        }
    }

    /// A motion controller other than a Wii Remote found by [`discover_pads`].
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct PadDeviceInfo {
        /// OS path (e.g. `/dev/hidraw5`).
        pub path: String,
        /// What it is.
        pub kind: crate::controllers::ControllerKind,
        /// How it is connected (hidapi's bus type; USB when unknown).
        pub link: crate::controllers::Link,
        /// Product string, if readable.
        pub product: Option<String>,
        /// Serial (Bluetooth address), if readable.
        pub serial: Option<String>,
    }

    /// Lists DualSense, DualShock 4, Switch Pro and Joy-Con controllers by vendor and
    /// product id, one entry per device node (a pad's first HID interface).
    pub fn discover_pads() -> Result<Vec<PadDeviceInfo>, TransportError> {
        use crate::controllers::ControllerKind;
        use crate::controllers::Link;
        let api = hidapi::HidApi::new().map_err(|e| TransportError::Io(e.to_string()))?;
        let mut out: Vec<PadDeviceInfo> = Vec::new();
        for d in api.device_list() {
            let Some(kind) = ControllerKind::from_ids(d.vendor_id(), d.product_id()) else {
                continue;
            };
            if kind == ControllerKind::WiiRemote {
                continue;
            }
            let path = d.path().to_string_lossy().into_owned();
            if out.iter().any(|o| o.path == path) {
                continue;
            }
            let link = match d.bus_type() {
                hidapi::BusType::Bluetooth => Link::Bluetooth,
                _ => Link::Usb,
            };
            out.push(PadDeviceInfo {
                path,
                kind,
                link,
                product: d.product_string().map(str::to_string),
                serial: d.serial_number().map(str::to_string),
            });
        }
        Ok(out)
    }
}
