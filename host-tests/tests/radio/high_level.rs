//! The high-level commander port 8: packets built byte by byte as cflib 0.1.34 `high_level_commander.py`
//! packs them (`struct.pack('<BBff?f', …)` for take-off/land, `'<BBBBfffff'` for go_to protocol ≥ 8,
//! `'<BBBfffff'` below, `'<BB'` for stop and group mask), decoded against the values that were packed.

use cfnav::flight::high_level::HlCommand;
use cfnav::radio::crtp::CrtpPacket;
use cfnav::radio_binding::high_level::{HighLevelService, HlError, HlPacket, decode, in_group};

/// cflib's `'<BBff?f'`: command, group mask, height, yaw, useCurrentYaw, duration.
fn takeoff_land(cmd: u8, mask: u8, height: f32, yaw: f32, use_current: bool, duration: f32) -> Vec<u8> {
    let mut v = vec![cmd, mask];
    v.extend_from_slice(&height.to_le_bytes());
    v.extend_from_slice(&yaw.to_le_bytes());
    v.push(u8::from(use_current));
    v.extend_from_slice(&duration.to_le_bytes());
    v
}

/// cflib's `'<BBBBfffff'`: GO_TO_2, group mask, relative, linear, x, y, z, yaw, duration.
fn go_to_2(mask: u8, relative: bool, linear: bool, xyz: [f32; 3], yaw: f32, duration: f32) -> Vec<u8> {
    let mut v = vec![12, mask, u8::from(relative), u8::from(linear)];
    for f in [xyz[0], xyz[1], xyz[2], yaw, duration] {
        v.extend_from_slice(&f.to_le_bytes());
    }
    v
}

#[test]
fn takeoff_2_and_land_2_decode_with_and_without_the_current_yaw() {
    let p = takeoff_land(7, 0, 0.5, 1.25, false, 2.0);
    assert_eq!(p.len(), 15);
    assert_eq!(
        decode(&p),
        Ok(HlPacket::Command {
            group_mask: 0,
            command: HlCommand::Takeoff {
                height_m: 0.5,
                yaw_rad: Some(1.25),
                duration_s: 2.0
            }
        })
    );
    // cflib `yaw=None` sends target_yaw 0.0 and useCurrentYaw True.
    assert_eq!(
        decode(&takeoff_land(8, 3, 0.0, 0.0, true, 3.5)),
        Ok(HlPacket::Command {
            group_mask: 3,
            command: HlCommand::Land {
                height_m: 0.0,
                yaw_rad: None,
                duration_s: 3.5
            }
        })
    );
}

#[test]
fn go_to_2_and_the_old_go_to_decode_every_flag() {
    for (relative, linear) in [(false, false), (true, false), (false, true), (true, true)] {
        let p = go_to_2(0, relative, linear, [1.0, -2.5, 0.75], -0.5, 4.0);
        assert_eq!(p.len(), 24);
        assert_eq!(
            decode(&p),
            Ok(HlPacket::Command {
                group_mask: 0,
                command: HlCommand::GoTo {
                    position_m: [1.0, -2.5, 0.75],
                    yaw_rad: -0.5,
                    duration_s: 4.0,
                    relative,
                    linear
                }
            })
        );
    }
    // Protocol < 8: '<BBBfffff' (no linear byte).
    let mut old = vec![4, 0, 1];
    for f in [0.1f32, 0.2, 0.3, 0.4, 0.5] {
        old.extend_from_slice(&f.to_le_bytes());
    }
    assert_eq!(
        decode(&old),
        Ok(HlPacket::Command {
            group_mask: 0,
            command: HlCommand::GoTo {
                position_m: [0.1, 0.2, 0.3],
                yaw_rad: 0.4,
                duration_s: 0.5,
                relative: true,
                linear: false
            }
        })
    );
}

#[test]
fn stop_group_mask_and_refusals() {
    assert_eq!(
        decode(&[3, 0]),
        Ok(HlPacket::Command {
            group_mask: 0,
            command: HlCommand::Stop
        })
    );
    assert_eq!(decode(&[0, 5]), Ok(HlPacket::SetGroupMask(5)));
    assert_eq!(decode(&[]), Err(HlError::Empty));
    assert_eq!(
        decode(&[7, 0, 1]),
        Err(HlError::WrongLength {
            command: 7,
            expected: 14,
            got: 2
        })
    );
    assert_eq!(decode(&[11, 0]), Err(HlError::Unsupported(11)));
    assert_eq!(decode(&[5, 0, 0, 0, 0, 0, 0, 0, 0]), Err(HlError::Unsupported(5)));
    assert_eq!(decode(&[42]), Err(HlError::Unknown(42)));
    let nan = takeoff_land(7, 0, f32::NAN, 0.0, false, 1.0);
    assert_eq!(decode(&nan), Err(HlError::NonFinite));
}

#[test]
fn group_masks_follow_stock_is_in_group() {
    assert!(in_group(0, 0));
    assert!(!in_group(2, 0));
    assert!(in_group(2, 0b110));
    assert!(!in_group(1, 0b110));
    let s = HighLevelService::new();
    s.set_now(5_000);
    // A drone in groups 2 and 3 ignores a command for group 1, takes one for all groups and one for group 2.
    s.handle_packet(&CrtpPacket::new(8, 0, &[0, 0b110]).unwrap()).unwrap();
    assert_eq!(s.group_mask(), 0b110);
    assert_eq!(
        s.handle_packet(&CrtpPacket::new(8, 0, &[3, 1]).unwrap()),
        Err(HlError::NotInGroup)
    );
    assert_eq!(s.take(), None);
    assert_eq!(s.take_error(), Some(HlError::NotInGroup));
    assert_eq!(s.take_error(), None);
    s.handle_packet(&CrtpPacket::new(8, 0, &[3, 2]).unwrap()).unwrap();
    assert_eq!(s.take(), Some((HlCommand::Stop, 5_000)));
    assert_eq!(s.take(), None);
    assert_eq!(
        s.handle_packet(&CrtpPacket::new(8, 1, &[3, 0]).unwrap()),
        Err(HlError::UnknownChannel(1))
    );
    assert_eq!(s.refused(), 2);
}

#[test]
fn no_byte_string_panics_the_decoder() {
    for cmd in 0..=20u8 {
        for n in 0..30usize {
            let mut v = vec![cmd];
            v.extend((0..n).map(|i| (i as u8).wrapping_mul(37).wrapping_add(cmd)));
            let _ = decode(&v);
        }
    }
}
