//! Why a motion controller that Linux lists cannot be used, and the exact fix.
//!
//! hidapi's hidraw backend lists controllers from sysfs without opening them, so one can be
//! listed and still be unusable: its `/dev/hidrawN` node is root-only (no udev rule), or a
//! kernel driver that talks to the device itself is bound to it (`hid-wiimote` for Wii
//! Remotes, `hid-nintendo` for Switch controllers; Sony's `hid-playstation` shares the
//! device and is no obstacle), or another program holds it (Dolphin; Steam's controller
//! support, which re-configures pads). [`LinuxDevices`] reads sysfs and `/dev` under root paths that
//! tests point at a fake tree, and turns what it finds (plus the error of a failed open) into
//! typed [`RemoteProblem`]s whose `Display` is the fix to apply.

use std::io;
use std::path::{Path, PathBuf};

/// Name of the kernel's Wii Remote HID driver in sysfs (`/sys/bus/hid/drivers/wiimote`).
pub const KERNEL_DRIVER: &str = "wiimote";

/// Name of the kernel's Switch controller driver in sysfs (`hid-nintendo`).
pub const NINTENDO_DRIVER: &str = "nintendo";

/// The udev rules that give the logged-in user access to every supported controller's
/// hidraw node (USB and Bluetooth alike: the HID id names vendor and product): Wii Remote
/// (057E:0306, 0330), Joy-Con L/R and Switch Pro (057E:2006, 2007, 2009), DualShock 4
/// (054C:05C4, 09CC, 0BA0), DualSense and Edge (054C:0CE6, 0DF2).
pub const UDEV_RULE: &str = "KERNEL==\"hidraw*\", KERNELS==\"*:057E:0306.*\", TAG+=\"uaccess\"\n\
KERNEL==\"hidraw*\", KERNELS==\"*:057E:0330.*\", TAG+=\"uaccess\"\n\
KERNEL==\"hidraw*\", KERNELS==\"*:057E:200[679].*\", TAG+=\"uaccess\"\n\
KERNEL==\"hidraw*\", KERNELS==\"*:054C:05C4.*\", TAG+=\"uaccess\"\n\
KERNEL==\"hidraw*\", KERNELS==\"*:054C:09CC.*\", TAG+=\"uaccess\"\n\
KERNEL==\"hidraw*\", KERNELS==\"*:054C:0BA0.*\", TAG+=\"uaccess\"\n\
KERNEL==\"hidraw*\", KERNELS==\"*:054C:0CE6.*\", TAG+=\"uaccess\"\n\
KERNEL==\"hidraw*\", KERNELS==\"*:054C:0DF2.*\", TAG+=\"uaccess\"";

/// Why a device node could not be opened (the `io::ErrorKind`s that matter here).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum OpenErrorKind {
    /// `EACCES`/`EPERM`: the node's permissions exclude this user.
    PermissionDenied,
    /// `EBUSY`: another program holds the device exclusively.
    Busy,
    /// The node vanished (the remote disconnected between listing and opening).
    NotFound,
    /// Anything else, with the OS message.
    Other(String),
}

impl From<&io::Error> for OpenErrorKind {
    fn from(e: &io::Error) -> Self {
        match e.kind() {
            io::ErrorKind::PermissionDenied => OpenErrorKind::PermissionDenied,
            io::ErrorKind::ResourceBusy => OpenErrorKind::Busy,
            io::ErrorKind::NotFound => OpenErrorKind::NotFound,
            _ => OpenErrorKind::Other(e.to_string()),
        }
    }
}

/// Why a remote is unusable. `Display` states the problem and the exact fix.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RemoteProblem {
    /// The hidraw node is not readable and writable by this user: a udev rule is missing.
    #[error(
        "{node} is not accessible to this user. Add /etc/udev/rules.d/60-motion-controllers.rules with\n{UDEV_RULE}\n\
         then run `sudo udevadm control --reload-rules && sudo udevadm trigger` and reconnect the controller."
    )]
    PermissionDenied {
        /// Device node, e.g. `/dev/hidraw3`.
        node: String,
    },
    /// The kernel's `hid-wiimote` driver is bound to the remote and consumes its reports.
    #[error(
        "the kernel's hid-wiimote driver is bound to {node} ({hid_id}) and talks to the remote itself. \
         Unbind it for this remote (as root):\n  \
         echo {hid_id} > /sys/bus/hid/drivers/wiimote/unbind && echo {hid_id} > /sys/bus/hid/drivers/hid-generic/bind\n\
         or for good: echo 'blacklist hid_wiimote' | sudo tee /etc/modprobe.d/wiimote.conf, then reconnect."
    )]
    KernelDriverBound {
        /// Device node.
        node: String,
        /// The HID device id, e.g. `0005:057E:0306.0007`.
        hid_id: String,
    },
    /// The kernel's `hid-nintendo` driver is bound to a Switch controller: it runs its own
    /// start sequence and subcommands, which collide with ours.
    #[error(
        "the kernel's hid-nintendo driver is bound to {node} ({hid_id}) and drives the controller itself. \
         Unbind it for this controller (as root):\n  \
         echo {hid_id} > /sys/bus/hid/drivers/nintendo/unbind && echo {hid_id} > /sys/bus/hid/drivers/hid-generic/bind\n\
         or for good: echo 'blacklist hid_nintendo' | sudo tee /etc/modprobe.d/nintendo.conf, then reconnect."
    )]
    NintendoDriverBound {
        /// Device node.
        node: String,
        /// The HID device id, e.g. `0005:057E:2009.0008`.
        hid_id: String,
    },
    /// Steam is running: its controller support opens pads and re-configures them (Switch
    /// report modes, Sony lightbars), so a pad may not answer or may change mode under us.
    #[error(
        "Steam is running and its controller support drives {node} too. Quit Steam, or turn off \
         Steam Input for this controller (Settings → Controller), then reconnect it."
    )]
    SteamRunning {
        /// Device node.
        node: String,
    },
    /// Another program holds the device.
    #[error(
        "{node} is busy: another program holds the remote (close other Wii Remote tools or \
         Dolphin, or find it with `sudo fuser -v {node}`)."
    )]
    Busy {
        /// Device node.
        node: String,
    },
    /// The node opened but the remote never answered the handshake.
    #[error(
        "{node} opened but the remote never answered. Press a button to wake it, or disconnect \
         and pair it again (`bluetoothctl`: pair, then connect at once)."
    )]
    NoAnswer {
        /// Device node.
        node: String,
    },
    /// Opening failed for another reason.
    #[error("{node} could not be opened: {message}")]
    OpenFailed {
        /// Device node.
        node: String,
        /// The OS message.
        message: String,
    },
    /// hidapi itself failed (e.g. no hidraw support).
    #[error("hidapi failed: {message}")]
    HidApi {
        /// hidapi's message.
        message: String,
    },
    /// The device answered but is not a supported Wii Remote.
    #[error("{node}: unsupported device ({what}); only Wii Remotes and Wii Remote Plus work")]
    Unsupported {
        /// Device node (or emulator id).
        node: String,
        /// What it is.
        what: String,
    },
}

impl RemoteProblem {
    /// The problem an open failure of `node` means when there is nothing more to read (no
    /// sysfs: other systems, the emulator).
    pub fn from_open_error(node: &str, kind: &OpenErrorKind) -> Self {
        let node = node.to_string();
        match kind {
            OpenErrorKind::PermissionDenied => RemoteProblem::PermissionDenied { node },
            OpenErrorKind::Busy => RemoteProblem::Busy { node },
            OpenErrorKind::NotFound => RemoteProblem::OpenFailed {
                node,
                message: "the device node vanished (the remote disconnected)".into(),
            },
            OpenErrorKind::Other(message) => RemoteProblem::OpenFailed {
                node,
                message: message.clone(),
            },
        }
    }

    /// The device node the problem is about, if any.
    pub fn node(&self) -> Option<&str> {
        match self {
            RemoteProblem::PermissionDenied { node }
            | RemoteProblem::KernelDriverBound { node, .. }
            | RemoteProblem::NintendoDriverBound { node, .. }
            | RemoteProblem::SteamRunning { node }
            | RemoteProblem::Busy { node }
            | RemoteProblem::NoAnswer { node }
            | RemoteProblem::OpenFailed { node, .. }
            | RemoteProblem::Unsupported { node, .. } => Some(node),
            RemoteProblem::HidApi { .. } => None,
        }
    }
}

/// A hidraw node that belongs to a motion controller.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HidrawNode {
    /// What it is.
    pub kind: crate::controllers::ControllerKind,
    /// Device node path under the device root (e.g. `/dev/hidraw3`).
    pub node: PathBuf,
    /// HID device id (`bus:vendor:product.instance`), e.g. `0005:057E:0306.0007`.
    pub hid_id: String,
    /// Name of the bound driver, if any (`wiimote` for the kernel driver, `hid-generic`).
    pub driver: Option<String>,
}

/// The user whose access is checked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UserIds {
    /// Effective user id.
    pub uid: u32,
    /// Effective and supplementary group ids.
    pub groups: Vec<u32>,
}

impl UserIds {
    /// This process's user, from `/proc/self/status` (`None` where that is unreadable).
    pub fn current() -> Option<Self> {
        let status = std::fs::read_to_string("/proc/self/status").ok()?;
        let field = |name: &str| -> Vec<u32> {
            status
                .lines()
                .find_map(|l| l.strip_prefix(name))
                .map(|rest| {
                    rest.split_whitespace()
                        .filter_map(|v| v.parse().ok())
                        .collect()
                })
                .unwrap_or_default()
        };
        let uid = *field("Uid:").get(1)?;
        let mut groups = field("Groups:");
        groups.extend(field("Gid:").get(1));
        Some(Self { uid, groups })
    }
}

/// Linux device information under a sysfs root and a device-node root.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinuxDevices {
    /// sysfs root (`/sys`).
    pub sys_root: PathBuf,
    /// Device-node root (`/dev`).
    pub dev_root: PathBuf,
    /// Whose access to check against the node's mode bits (`None`: only the error of an
    /// actual open decides permissions).
    pub user: Option<UserIds>,
}

impl LinuxDevices {
    /// The running system: `/sys`, `/dev`, this process's user.
    pub fn system() -> Self {
        Self {
            sys_root: PathBuf::from("/sys"),
            dev_root: PathBuf::from("/dev"),
            user: UserIds::current(),
        }
    }

    /// A tree under other roots (tests), checked for `user`.
    pub fn at(sys_root: impl Into<PathBuf>, dev_root: impl Into<PathBuf>, user: UserIds) -> Self {
        Self {
            sys_root: sys_root.into(),
            dev_root: dev_root.into(),
            user: Some(user),
        }
    }

    /// Every hidraw node whose HID device is a Wii Remote (by vendor/product id or name).
    pub fn wiimote_nodes(&self) -> Vec<HidrawNode> {
        let mut nodes = self.controller_nodes();
        nodes.retain(|n| n.kind == crate::controllers::ControllerKind::WiiRemote);
        nodes
    }

    /// Every hidraw node whose HID device is a supported motion controller.
    pub fn controller_nodes(&self) -> Vec<HidrawNode> {
        let Ok(dir) = std::fs::read_dir(self.sys_root.join("class/hidraw")) else {
            return Vec::new();
        };
        let mut out: Vec<HidrawNode> = dir
            .flatten()
            .filter_map(|entry| {
                let device = entry.path().join("device");
                let uevent = std::fs::read_to_string(device.join("uevent")).ok()?;
                let kind = controller_of_uevent(&uevent)?;
                let hid_id = std::fs::canonicalize(&device)
                    .ok()
                    .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
                    .filter(|n| n.contains(':'))
                    .unwrap_or_else(|| hid_id_from_uevent(&uevent));
                let driver = std::fs::read_link(device.join("driver"))
                    .ok()
                    .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()));
                Some(HidrawNode {
                    kind,
                    node: self.dev_root.join(entry.file_name()),
                    hid_id,
                    driver,
                })
            })
            .collect();
        out.sort_by(|a, b| a.node.cmp(&b.node));
        out
    }

    /// The problems of the remote at `node` (a path under the device root), given how opening
    /// it failed (`None`: not tried, or it opened). Empty when nothing is wrong that this can
    /// see.
    pub fn diagnose(&self, node: &Path, open_error: Option<&OpenErrorKind>) -> Vec<RemoteProblem> {
        let name = node.to_string_lossy().into_owned();
        let mut out = Vec::new();
        if let Some(found) = self.controller_nodes().into_iter().find(|n| n.node == node) {
            match found.driver.as_deref() {
                Some(KERNEL_DRIVER) => out.push(RemoteProblem::KernelDriverBound {
                    node: name.clone(),
                    hid_id: found.hid_id,
                }),
                Some(NINTENDO_DRIVER) => out.push(RemoteProblem::NintendoDriverBound {
                    node: name.clone(),
                    hid_id: found.hid_id,
                }),
                _ => {}
            }
        }
        let denied = match open_error {
            Some(OpenErrorKind::PermissionDenied) => true,
            Some(_) => false,
            None => self.mode_denies(node),
        };
        if denied {
            out.push(RemoteProblem::PermissionDenied { node: name.clone() });
        }
        match open_error {
            Some(OpenErrorKind::Busy) => out.push(RemoteProblem::Busy { node: name }),
            Some(OpenErrorKind::Other(message)) => out.push(RemoteProblem::OpenFailed {
                node: name,
                message: message.clone(),
            }),
            _ => {}
        }
        out
    }

    /// Problems of every controller node (before any open: permissions from mode bits).
    pub fn diagnose_all(&self) -> Vec<RemoteProblem> {
        self.controller_nodes()
            .iter()
            .flat_map(|n| self.diagnose(&n.node, None))
            .collect()
    }

    /// Whether the node's mode bits deny read+write to [`Self::user`] (ACLs are not read: an
    /// actual open's error is authoritative).
    #[cfg(unix)]
    fn mode_denies(&self, node: &Path) -> bool {
        use std::os::unix::fs::MetadataExt;
        let (Some(user), Ok(meta)) = (&self.user, std::fs::metadata(node)) else {
            return false;
        };
        let mode = meta.mode();
        let rw = |shift: u32| (mode >> shift) & 0o6 == 0o6;
        let allowed = user.uid == 0
            || (meta.uid() == user.uid && rw(6))
            || (user.groups.contains(&meta.gid()) && rw(3))
            || rw(0);
        !allowed
    }

    /// Mode bits exist on Unix only: elsewhere an actual open's error decides.
    #[cfg(not(unix))]
    fn mode_denies(&self, _node: &Path) -> bool {
        false
    }
}

/// Tries to open `node` read+write as hidapi will, and reports why that fails.
pub fn probe_open(node: &Path) -> Result<(), OpenErrorKind> {
    std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(node)
        .map(drop)
        .map_err(|e| OpenErrorKind::from(&e))
}

/// The controller a hidraw device's `uevent` names (`HID_ID=bus:vendor:product`, or a Wii
/// Remote's `RVL-CNT` name for clones with other ids).
fn controller_of_uevent(uevent: &str) -> Option<crate::controllers::ControllerKind> {
    use crate::controllers::ControllerKind;
    let ids = uevent
        .lines()
        .find_map(|l| l.strip_prefix("HID_ID="))
        .and_then(|id| {
            let mut parts = id.split(':').skip(1);
            let vendor = u16::from_str_radix(parts.next()?, 16).ok()?;
            let product = u16::from_str_radix(parts.next()?, 16).ok()?;
            ControllerKind::from_ids(vendor, product)
        });
    ids.or_else(|| {
        uevent
            .to_ascii_uppercase()
            .contains("RVL-CNT")
            .then_some(ControllerKind::WiiRemote)
    })
}

/// Whether a process named `steam` runs (from `/proc/*/comm` under `proc_root`).
pub fn steam_running(proc_root: &Path) -> bool {
    let Ok(dir) = std::fs::read_dir(proc_root) else {
        return false;
    };
    dir.flatten().any(|e| {
        e.file_name()
            .to_string_lossy()
            .bytes()
            .all(|b| b.is_ascii_digit())
            && std::fs::read_to_string(e.path().join("comm")).is_ok_and(|c| c.trim() == "steam")
    })
}

/// `HID_ID=0005:0000057E:00000306` → `0005:057E:0306` (the instance suffix is unknown here).
fn hid_id_from_uevent(uevent: &str) -> String {
    uevent
        .lines()
        .find_map(|l| l.strip_prefix("HID_ID="))
        .map(|id| {
            id.split(':')
                .map(|p| {
                    let t = p.trim_start_matches('0');
                    format!("{t:0>4}")
                })
                .collect::<Vec<_>>()
                .join(":")
        })
        .unwrap_or_else(|| "<HID id>".to_string())
}
