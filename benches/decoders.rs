//! Pad report decoders: reports per second for every kind and link, on reports from the
//! emulators (byte-identical to the hardware's layouts). Run with
//! `cargo bench --bench decoders`; target ≥ 1 M reports/s on the project's 2-core machine.

use bevy_wii_deform::controllers::pads::{EmulatedPad, PadDecoder, PadEmulatorConfig};
use bevy_wii_deform::controllers::transport::Transport;
use bevy_wii_deform::controllers::{ControllerKind, Link, sony, switch};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

/// `n` full input reports of an emulated pad (held still, face up).
fn reports(kind: ControllerKind, link: Link, n: usize) -> Vec<Vec<u8>> {
    let mut pad = EmulatedPad::new(PadEmulatorConfig::new(kind, link));
    if switch::is_switch(kind) {
        pad.write(&switch::subcommand_report(
            1,
            switch::SUB_INPUT_MODE,
            &[0x30],
        ))
        .unwrap();
        pad.write(&switch::subcommand_report(2, switch::SUB_IMU, &[0x01]))
            .unwrap();
    } else {
        let (id, len) = sony::calibration_report(kind, link);
        let mut buf = vec![0u8; len];
        buf[0] = id;
        pad.get_feature_report(&mut buf).unwrap();
    }
    let mut out = Vec::with_capacity(n);
    let mut buf = [0u8; 128];
    while out.len() < n {
        let len = pad.read_timeout(&mut buf, 50).unwrap();
        let r = &buf[..len];
        let full = matches!(r.first(), Some(&0x30) | Some(&0x31) | Some(&0x11))
            || (r.first() == Some(&0x01) && r.len() == 64);
        if full && !(r[0] == 0x30 && r[13..49].iter().all(|&b| b == 0)) {
            out.push(r.to_vec());
        }
    }
    out
}

fn decoders(c: &mut Criterion) {
    let mut group = c.benchmark_group("decode");
    for (kind, link) in [
        (ControllerKind::DualSense, Link::Usb),
        (ControllerKind::DualSense, Link::Bluetooth),
        (ControllerKind::DualShock4, Link::Bluetooth),
        (ControllerKind::SwitchPro, Link::Bluetooth),
        (ControllerKind::JoyConRight, Link::Bluetooth),
    ] {
        let reports = reports(kind, link, 1000);
        let decoder = PadDecoder::new(kind, link).unwrap();
        group.throughput(Throughput::Elements(reports.len() as u64));
        group.bench_function(format!("{}_{}", kind.name(), link.name()), |b| {
            b.iter(|| {
                let mut samples = 0usize;
                for r in &reports {
                    let decoded = decoder.decode(std::hint::black_box(r)).unwrap();
                    samples += decoded.samples().len();
                }
                samples
            })
        });
    }
    group.finish();
}

criterion_group!(benches, decoders);
criterion_main!(benches);
