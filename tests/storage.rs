//! The flash parameter record: round trip, corruption detection, rejection of foreign records,
//! and no panic on arbitrary bytes.

use piezo_drive::defaults::controller_config;
use piezo_drive::storage::{self, StorageError, MAGIC, PAYLOAD_LEN, RECORD_LEN, VERSION};
use proptest::prelude::*;

#[test]
fn crc32_check_value() {
    // The catalogue check value of CRC-32/ISO-HDLC.
    assert_eq!(storage::crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(storage::crc32(b""), 0);
}

#[test]
fn defaults_round_trip() {
    let d = controller_config();
    let rec = storage::encode(&d);
    assert_eq!(rec.len(), RECORD_LEN);
    assert_eq!(&rec[0..4], &MAGIC.to_le_bytes());
    assert_eq!(u16::from_le_bytes([rec[4], rec[5]]), VERSION);
    assert_eq!(usize::from(u16::from_le_bytes([rec[6], rec[7]])), PAYLOAD_LEN);
    assert_eq!(storage::decode(&rec, &d), Ok(d));
}

#[test]
fn changed_settings_round_trip_and_rest_from_defaults() {
    let d = controller_config();
    let mut c = d;
    c.kp_per_s = 55.5;
    c.preload.zero_word = 123;
    c.preload.newton_per_word = -0.02;
    c.travel_min_nm = -1_234_567;
    c.travel_max_nm = 7_654_321;
    c.feedforward = false;
    c.drive_freq_hz = 1500.0;
    c.encoder_jump_counts = 1000;
    c.expected_load_n = -2.0;
    let rec = storage::encode(&c);
    assert_eq!(storage::decode(&rec, &d), Ok(c));
    // Longer input (a whole flash page, erased after the record) decodes the same.
    let mut page = vec![0xFFu8; 2048];
    page[..RECORD_LEN].copy_from_slice(&rec);
    assert_eq!(storage::decode(&page, &d), Ok(c));
}

#[test]
fn every_single_bit_flip_is_detected() {
    let d = controller_config();
    let rec = storage::encode(&d);
    for byte in 0..RECORD_LEN {
        for bit in 0..8 {
            let mut bad = rec;
            bad[byte] ^= 1 << bit;
            assert!(storage::decode(&bad, &d).is_err(), "flip of bit {bit} in byte {byte} accepted");
        }
    }
}

#[test]
fn erased_flash_wrong_version_and_length_are_rejected() {
    let d = controller_config();
    assert_eq!(storage::decode(&[0xFF; RECORD_LEN], &d), Err(StorageError::NoRecord));
    assert_eq!(storage::decode(&[], &d), Err(StorageError::TooShort));
    let rec = storage::encode(&d);
    assert_eq!(storage::decode(&rec[..RECORD_LEN - 1], &d), Err(StorageError::TooShort));

    // Another version with a valid CRC is still refused.
    let mut v2 = rec;
    v2[4..6].copy_from_slice(&(VERSION + 1).to_le_bytes());
    let crc = storage::crc32(&v2[..RECORD_LEN - 4]);
    v2[RECORD_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(storage::decode(&v2, &d), Err(StorageError::WrongVersion(VERSION + 1)));

    let mut len = rec;
    len[6..8].copy_from_slice(&(PAYLOAD_LEN as u16 - 1).to_le_bytes());
    let crc = storage::crc32(&len[..RECORD_LEN - 4]);
    len[RECORD_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(storage::decode(&len, &d), Err(StorageError::WrongLength(PAYLOAD_LEN as u16 - 1)));
}

#[test]
fn out_of_range_values_are_rejected_even_with_a_good_crc() {
    let d = controller_config();
    let cases: [fn(&mut piezo_drive::controller::ControllerConfig); 7] = [
        |c| c.kp_per_s = f32::NAN,
        |c| c.speed_fraction = 2.0,
        |c| c.drive_freq_hz = 10_000.0,
        |c| c.preload_max_n = c.preload_min_n,
        |c| c.travel_max_nm = c.travel_min_nm,
        |c| c.preload.min_valid_word = c.preload.max_valid_word,
        |c| c.max_drive_v = 500.0,
    ];
    for (i, f) in cases.iter().enumerate() {
        let mut c = d;
        f(&mut c);
        assert_eq!(storage::validate(&c), Err(StorageError::OutOfRange), "case {i}");
        let rec = storage::encode(&c);
        assert_eq!(storage::decode(&rec, &d), Err(StorageError::OutOfRange), "case {i}");
    }
    // The encoder resolution is the hardware's (read-only): out of range it is refused (so WPA
    // refuses it), but the record does not hold it, so it decodes to the build's value.
    let mut c = d;
    c.encoder_nm_per_count = 0;
    assert_eq!(storage::validate(&c), Err(StorageError::OutOfRange));
    assert_eq!(storage::decode(&storage::encode(&c), &d), Ok(d));
    // A non-0/1 bool byte is refused.
    let mut rec = storage::encode(&d);
    let ff = storage::offset_of(0x1005).unwrap();
    assert_eq!(rec[ff], 1);
    rec[ff] = 2;
    let crc = storage::crc32(&rec[..RECORD_LEN - 4]);
    rec[RECORD_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(storage::decode(&rec, &d), Err(StorageError::OutOfRange));
}

proptest! {
    #[test]
    fn arbitrary_bytes_are_refused_without_a_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        // Random bytes carry a valid header and CRC with probability ~2^-48: decode refuses them
        // (and must not panic on any length).
        let d = controller_config();
        prop_assert!(storage::decode(&bytes, &d).is_err());
    }

    #[test]
    fn arbitrary_payload_with_valid_header_and_crc_never_panics(
        payload in proptest::collection::vec(any::<u8>(), PAYLOAD_LEN..=PAYLOAD_LEN)
    ) {
        let d = controller_config();
        let mut rec = storage::encode(&d);
        rec[8..8 + PAYLOAD_LEN].copy_from_slice(&payload);
        let crc = storage::crc32(&rec[..RECORD_LEN - 4]);
        rec[RECORD_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
        // Header and CRC are valid, so the payload's values decide: either every value is in
        // range (then the record round-trips) or the refusal says so, never a CRC or header error.
        match storage::decode(&rec, &d) {
            Ok(c) => {
                prop_assert!(storage::validate(&c).is_ok());
                prop_assert_eq!(storage::encode(&c), rec);
            }
            Err(e) => prop_assert_eq!(e, StorageError::OutOfRange),
        }
    }

    #[test]
    fn valid_configs_round_trip(kp in 0.0f32..1e4, gain in 0.0f32..=1.0, f in 500.0f32..=2200.0,
                                lo in -1_000_000_000i64..0, hi in 1i64..1_000_000_000, zero in any::<u16>()) {
        let d = controller_config();
        let mut c = d;
        c.kp_per_s = kp;
        c.fb_kp_v_per_nm = gain;
        c.drive_freq_hz = f;
        c.travel_min_nm = lo;
        c.travel_max_nm = hi;
        c.preload.zero_word = zero;
        prop_assert_eq!(storage::decode(&storage::encode(&c), &d), Ok(c));
    }
}

/// A configuration with every stored setting away from its default (valid together).
fn changed() -> piezo_drive::controller::ControllerConfig {
    use piezo_drive::controller::ReferenceSignal;
    let mut c = controller_config();
    c.kp_per_s = 55.5;
    c.ki_n_per_nm_s = 0.002;
    c.following_error_limit_nm = 40_000.0;
    c.velocity_max_nm_s = 1.5e6;
    c.accel_max_nm_s2 = 5e8;
    c.decel_max_nm_s2 = 2.5e8;
    c.travel_max_nm = 20_000_000;
    c.travel_min_nm = -3_500_000;
    c.on_target_window_nm = 100;
    c.settle_time_s = 0.02;
    c.drive_freq_hz = 1500.0;
    c.max_drive_v = 90.0;
    c.speed_fraction = 0.5;
    c.accel_fraction = 0.6;
    c.feedforward = false;
    c.fb_kp_v_per_nm = 0.004;
    c.fb_ki_v_per_nm_s = 0.3;
    c.expected_load_n = -1.25;
    c.profile_wait_lag_nm = 3000.0;
    c.approach_speed_nm_s = 250_000.0;
    c.fine_window_nm = 500.0;
    c.stall_time_s = 0.08;
    c.encoder_jump_counts = 300;
    c.preload_min_n = 4.0;
    c.preload_max_n = 20.0;
    c.preload.zero_word = 7;
    c.preload.newton_per_word = 0.0125;
    c.preload.min_valid_word = 3;
    c.preload.max_valid_word = 4000;
    c.preload.filter_alpha = 0.05;
    c.reference_signal = ReferenceSignal::NegativeLimit;
    c.reference_position_nm = -1_000_000;
    c.reference_drive_v = 40.0;
    c.reference_timeout_s = 100.0;
    c.moving_mass_kg = 0.45;
    c.mu_dynamic = 0.28;
    c.tangential_scale = 0.19;
    c.normal_force_ratio = 0.6;
    c.rail_coulomb_n = 0.4;
    c.rail_viscous_n_s_per_m = 2.5;
    c.drive_freq_min_hz = 900.0;
    c.encoder_loss_counts = 120;
    c.idn_c867_compatible = true;
    c.contact_table = true;
    c.limit_switches_enabled = true;
    c.limit_switch_active_high = true;
    c
}

/// Issue 15: `WPA` on the board kept neither `VEL`/`ACC`/`DEC` nor the referencing settings
/// (the record had no fields for them; decoding gave the defaults back).
#[test]
fn motion_limits_and_referencing_settings_are_stored() {
    use piezo_drive::controller::ReferenceSignal;
    let d = controller_config();
    let mut c = d;
    c.velocity_max_nm_s = 1.5e6;
    c.accel_max_nm_s2 = 5e8;
    c.decel_max_nm_s2 = 2.5e8;
    c.reference_signal = ReferenceSignal::NegativeLimit;
    c.reference_position_nm = -1_000_000;
    c.reference_drive_v = 40.0;
    c.reference_timeout_s = 100.0;
    let back = storage::decode(&storage::encode(&c), &d).unwrap();
    assert_eq!(back.velocity_max_nm_s, 1.5e6);
    assert_eq!(back.accel_max_nm_s2, 5e8);
    assert_eq!(back.decel_max_nm_s2, 2.5e8);
    assert_eq!(back.reference_signal, ReferenceSignal::NegativeLimit);
    assert_eq!(back.reference_position_nm, -1_000_000);
    assert_eq!(back.reference_drive_v, 40.0);
    assert_eq!(back.reference_timeout_s, 100.0);
    assert_eq!(back, c);
    // Every setting at once.
    assert_eq!(storage::decode(&storage::encode(&changed()), &d), Ok(changed()));
}

/// Issue 15: the record's validator allowed an encoder jump limit up to i16::MAX, the
/// protocol's up to i32::MAX. The 16-bit counter's change per period is an i16, so a larger
/// limit could never trip: one limit, everywhere.
#[test]
fn encoder_jump_limit_is_the_same_for_the_controller_and_the_record() {
    use piezo_drive::controller::{validate_settings, Controller};
    let d = controller_config();
    for (jump, ok) in [(0, false), (1, true), (32_767, true), (32_768, false), (i32::MAX, false)] {
        let c = piezo_drive::controller::ControllerConfig { encoder_jump_counts: jump, ..d };
        assert_eq!(validate_settings(&c).is_ok(), ok, "{jump}");
        assert_eq!(Controller::new(c).is_ok(), ok, "{jump}");
        assert_eq!(storage::validate(&c).is_ok(), ok, "{jump}");
    }
}

#[test]
fn what_the_controller_accepts_the_record_stores() {
    // Values far from the defaults that the controller takes (SPA accepts them): WPA must not
    // refuse them (it did for a gain above 1e4, a load beyond 1000 N, a stall time over 10 s).
    let d = controller_config();
    let cases: [fn(&mut piezo_drive::controller::ControllerConfig); 6] = [
        |c| c.kp_per_s = 3.4e7,
        |c| c.ki_n_per_nm_s = 2.0,
        |c| c.expected_load_n = -5000.0,
        |c| c.stall_time_s = 60.0,
        |c| c.settle_time_s = 20.0,
        |c| c.preload.filter_alpha = 1e-5,
    ];
    for (i, f) in cases.iter().enumerate() {
        let mut c = d;
        f(&mut c);
        assert!(piezo_drive::controller::Controller::new(c).is_ok(), "case {i}");
        assert_eq!(storage::decode(&storage::encode(&c), &d), Ok(c), "case {i}");
    }
}

/// Little-endian bytes of the values, in the order given.
#[derive(Clone, Copy)]
enum V {
    F(f32),
    I(i64),
    I32(i32),
    U32(u32),
    W(u16),
    B(u8),
}

fn record(version: u16, values: &[V]) -> Vec<u8> {
    let mut payload = Vec::new();
    for v in values {
        match v {
            V::F(x) => payload.extend_from_slice(&x.to_le_bytes()),
            V::I(x) => payload.extend_from_slice(&x.to_le_bytes()),
            V::I32(x) => payload.extend_from_slice(&x.to_le_bytes()),
            V::U32(x) => payload.extend_from_slice(&x.to_le_bytes()),
            V::W(x) => payload.extend_from_slice(&x.to_le_bytes()),
            V::B(x) => payload.push(*x),
        }
    }
    let mut rec = b"PZDP".to_vec();
    rec.extend_from_slice(&version.to_le_bytes());
    rec.extend_from_slice(&(payload.len() as u16).to_le_bytes());
    rec.extend_from_slice(&payload);
    let crc = storage::crc32(&rec);
    rec.extend_from_slice(&crc.to_le_bytes());
    rec
}

/// The version-9 layout, written out by hand: every stored setting in table order, in its
/// type's width. A change here is a new format version. Version 4 was the same without the
/// lowest drive frequency at the end, version 3 also without the calibrated motor, version 2
/// also without the moving mass; such records still load, what they lack from the defaults.
#[test]
fn version_9_record_byte_for_byte_and_versions_8_to_2_still_load() {
    use V::*;
    let v2_fields = [
        F(55.5),       // 0x1 kp
        F(0.002),      // 0x2 ki
        F(40_000.0),   // 0x8 following error (nm)
        F(1.5e6),      // 0xA VEL (nm/s)
        F(5e8),        // 0xB ACC
        F(2.5e8),      // 0xC DEC
        I(20_000_000), // 0x15 travel max (nm)
        I(-3_500_000), // 0x30 travel min
        I(100),        // 0x36 settling window
        F(0.02),       // 0x3F settling time
        F(1500.0),     // 0x1001 drive frequency
        F(90.0),       // 0x1002 maximum drive
        F(0.5),        // 0x1003 speed share
        F(0.6),        // 0x1004 thrust share
        B(0),          // 0x1005 feedforward
        F(0.004),      // 0x1006 plain kp
        F(0.3),        // 0x1007 plain ki
        F(-1.25),      // 0x1008 expected load
        F(3000.0),     // 0x1009 profile wait lag
        F(250_000.0),  // 0x100A approach speed
        F(500.0),      // 0x100B fine window
        F(0.08),       // 0x100D stall time
        I32(300),      // 0x100E encoder jump
        F(4.0),        // 0x100F preload min
        F(20.0),       // 0x1010 preload max
        W(7),          // 0x1011 zero word
        F(0.0125),     // 0x1012 N per word
        W(3),          // 0x1013 lowest valid word
        W(4000),       // 0x1014 highest valid word
        F(0.05),       // 0x1015 filter
        B(1),          // 0x1016 reference signal: negative limit
        I(-1_000_000), // 0x1017 reference position
        F(40.0),       // 0x1018 reference drive
        F(100.0),      // 0x1019 reference timeout
    ];
    let mut v3_fields = v2_fields.to_vec();
    v3_fields.push(F(0.45)); // 0x101A moving mass (kg)
    let mut v4_fields = v3_fields.clone();
    v4_fields.extend([
        F(0.28), // 0x101B friction coefficient
        F(0.19), // 0x101C tangential scale
        F(0.6),  // 0x101D normal force ratio
        F(0.4),  // 0x101E guide Coulomb friction (N)
        F(2.5),  // 0x101F guide viscous friction (N per m/s)
    ]);
    let mut v5_fields = v4_fields.clone();
    v5_fields.push(F(900.0)); // 0x1022 lowest drive frequency (Hz)
    let mut v6_fields = v5_fields.clone();
    v6_fields.push(I32(120)); // 0x1023 encoder loss limit (counts)
    let mut v7_fields = v6_fields.clone();
    v7_fields.push(B(1)); // 0x1040 C-867 compatible identity
                          // Format 8 puts its row in table order, before the identity of format 7.
    let mut v8_fields = v6_fields.clone();
    v8_fields.push(B(1)); // 0x1024 contact-model table
    v8_fields.push(B(1)); // 0x1040 C-867 compatible identity

    // Format 9 adds the limit switch rows, in table order after the contact-model row.
    let mut v9_fields = v6_fields.clone();
    v9_fields.extend([
        B(1), // 0x1024 contact-model table
        B(1), // 0x1025 limit switches read
        B(1), // 0x1026 limit switches active high
        B(1), // 0x1040 C-867 compatible identity
    ]);
    let expected = record(9, &v9_fields);
    assert_eq!(VERSION, 9);
    assert_eq!(PAYLOAD_LEN, 176);
    assert_eq!(RECORD_LEN, 188);
    assert_eq!(storage::encode(&changed()).to_vec(), expected);
    assert_eq!(storage::decode(&expected, &controller_config()), Ok(changed()));
    // Version 8: everything but the limit switch settings, from the defaults.
    let d = controller_config();
    let v8 = record(8, &v8_fields);
    assert_eq!(v8.len(), 8 + 174 + 4);
    let mut want = changed();
    (want.limit_switches_enabled, want.limit_switch_active_high) =
        (d.limit_switches_enabled, d.limit_switch_active_high);
    assert_eq!(storage::decode(&v8, &d), Ok(want));
    // Version 7: also the contact-model table setting from the defaults.
    let v7 = record(7, &v7_fields);
    assert_eq!(v7.len(), 8 + 173 + 4);
    want.contact_table = d.contact_table;
    assert_eq!(storage::decode(&v7, &d), Ok(want));
    // Version 6: also the identity setting from the defaults.
    let v6 = record(6, &v6_fields);
    assert_eq!(v6.len(), 8 + 172 + 4);
    want.idn_c867_compatible = d.idn_c867_compatible;
    assert_eq!(storage::decode(&v6, &d), Ok(want));
    // Version 5: also the encoder loss limit from the defaults.
    let v5 = record(5, &v5_fields);
    assert_eq!(v5.len(), 8 + 168 + 4);
    want.encoder_loss_counts = d.encoder_loss_counts;
    assert_eq!(storage::decode(&v5, &d), Ok(want));
    // Version 4: also the lowest drive frequency from the defaults.
    let v4 = record(4, &v4_fields);
    assert_eq!(v4.len(), 8 + 164 + 4);
    want.drive_freq_min_hz = d.drive_freq_min_hz;
    assert_eq!(storage::decode(&v4, &d), Ok(want));
    // Version 3: also the calibrated motor from the defaults.
    let v3 = record(3, &v3_fields);
    assert_eq!(v3.len(), 8 + 144 + 4);
    (want.mu_dynamic, want.tangential_scale, want.normal_force_ratio) =
        (d.mu_dynamic, d.tangential_scale, d.normal_force_ratio);
    (want.rail_coulomb_n, want.rail_viscous_n_s_per_m) = (d.rail_coulomb_n, d.rail_viscous_n_s_per_m);
    assert_eq!(storage::decode(&v3, &d), Ok(want));
    // Version 2: also the mass from the defaults.
    let v2 = record(2, &v2_fields);
    assert_eq!(v2.len(), 8 + 140 + 4);
    want.moving_mass_kg = d.moving_mass_kg;
    assert_eq!(storage::decode(&v2, &d), Ok(want));
}

/// A record written by the firmware before the settings table (version 1, 119 payload bytes)
/// still loads; what it did not hold comes from the defaults, the fine-mode gain it held is
/// gone.
#[test]
fn version_1_record_still_loads() {
    use V::*;
    let v1 = record(
        1,
        &[
            U32(50),       // encoder resolution (read-only)
            W(7),          // zero word
            F(0.0125),     // N per word
            W(3),          // lowest valid word
            W(4000),       // highest valid word
            F(0.05),       // filter
            F(4.0),        // preload min
            F(20.0),       // preload max
            F(90.0),       // maximum drive
            F(40_000.0),   // following error (nm)
            F(0.08),       // stall time
            I32(300),      // encoder jump
            I(-3_500_000), // travel min (nm)
            I(20_000_000), // travel max
            I(100),        // settling window
            F(0.02),       // settling time
            F(1500.0),     // drive frequency
            F(0.5),        // speed share
            F(0.6),        // thrust share
            F(55.5),       // kp
            F(0.002),      // ki
            B(0),          // feedforward
            F(0.004),      // plain kp
            F(0.3),        // plain ki
            F(-1.25),      // expected load
            F(3000.0),     // profile wait lag
            F(250_000.0),  // approach speed
            F(500.0),      // fine window
            F(0.5),        // fine-mode gain (no longer a setting)
        ],
    );
    assert_eq!(v1.len(), 8 + 119 + 4);
    let d = controller_config();
    let mut expected = changed();
    // Not in version 1: from the defaults.
    expected.velocity_max_nm_s = d.velocity_max_nm_s;
    expected.accel_max_nm_s2 = d.accel_max_nm_s2;
    expected.decel_max_nm_s2 = d.decel_max_nm_s2;
    expected.reference_signal = d.reference_signal;
    expected.reference_position_nm = d.reference_position_nm;
    expected.reference_drive_v = d.reference_drive_v;
    expected.reference_timeout_s = d.reference_timeout_s;
    expected.moving_mass_kg = d.moving_mass_kg;
    (expected.mu_dynamic, expected.tangential_scale, expected.normal_force_ratio) =
        (d.mu_dynamic, d.tangential_scale, d.normal_force_ratio);
    (expected.rail_coulomb_n, expected.rail_viscous_n_s_per_m) = (d.rail_coulomb_n, d.rail_viscous_n_s_per_m);
    expected.drive_freq_min_hz = d.drive_freq_min_hz;
    expected.encoder_loss_counts = d.encoder_loss_counts;
    expected.idn_c867_compatible = d.idn_c867_compatible;
    expected.contact_table = d.contact_table;
    (expected.limit_switches_enabled, expected.limit_switch_active_high) =
        (d.limit_switches_enabled, d.limit_switch_active_high);
    assert_eq!(storage::decode(&v1, &d), Ok(expected));
    // As read from a flash page (erased bytes after it).
    let mut page = vec![0xFFu8; 2048];
    page[..v1.len()].copy_from_slice(&v1);
    assert_eq!(storage::decode(&page, &d), Ok(expected));
    // Its checks still hold: a flipped bit, a wrong length.
    let mut bad = v1.clone();
    bad[20] ^= 4;
    assert_eq!(storage::decode(&bad, &d), Err(StorageError::BadCrc));
    let short = record(1, &[F(1.0)]);
    assert_eq!(storage::decode(&short, &d), Err(StorageError::WrongLength(4)));
}

#[test]
fn every_setting_is_stored_unless_read_only_and_every_default_comes_from_somewhere() {
    use piezo_drive::controller::{ControllerConfig, ReferenceSignal};
    use piezo_drive::defaults::{with_defaults, REFERENCE_BOARD};
    use piezo_drive::sensors::PreloadCalibration;
    use piezo_drive::settings::SETTINGS;
    for s in SETTINGS {
        // An alias (another row's value in PI's units, Keep::Volatile) has nothing of its own.
        assert_eq!(s.stored, !s.read_only && s.keep != piezo_drive::settings::Keep::Volatile, "{}", s.name);
        assert_eq!(storage::offset_of(s.id).is_some(), s.stored, "{}", s.name);
    }
    // Every field of the defaults is set by the table or the hardware, whatever it held before:
    // from zeros, and from NaN, all-ones integers, true and the second choice. Written out field
    // by field, so that a new field without a row fails to compile here first.
    let (f, w, n) = (f32::NAN, u16::MAX, -1i64);
    let odd = ControllerConfig {
        loop_hz: n as u32,
        dac: REFERENCE_BOARD.dac,
        motor: REFERENCE_BOARD.motor,
        encoder_nm_per_count: n as u32,
        preload: PreloadCalibration {
            zero_word: w,
            newton_per_word: f,
            min_valid_word: w,
            max_valid_word: w,
            filter_alpha: f,
        },
        preload_min_n: f,
        preload_max_n: f,
        drive_freq_hz: f,
        max_drive_v: f,
        speed_fraction: f,
        accel_fraction: f,
        kp_per_s: f,
        ki_n_per_nm_s: f,
        feedforward: true,
        fb_kp_v_per_nm: f,
        fb_ki_v_per_nm_s: f,
        expected_load_n: f,
        profile_wait_lag_nm: f,
        approach_speed_nm_s: f,
        fine_window_nm: f,
        on_target_window_nm: n,
        settle_time_s: f,
        following_error_limit_nm: f,
        stall_time_s: f,
        encoder_jump_counts: n as i32,
        encoder_loss_counts: n as i32,
        travel_min_nm: n,
        travel_max_nm: n,
        velocity_max_nm_s: f,
        accel_max_nm_s2: f,
        decel_max_nm_s2: f,
        reference_signal: ReferenceSignal::NegativeLimit,
        reference_position_nm: n,
        reference_drive_v: f,
        reference_timeout_s: f,
        moving_mass_kg: f,
        mu_dynamic: f,
        tangential_scale: f,
        normal_force_ratio: f,
        rail_coulomb_n: f,
        rail_viscous_n_s_per_m: f,
        drive_freq_min_hz: f,
        idn_c867_compatible: true,
        contact_table: true,
        limit_switches_enabled: true,
        limit_switch_active_high: true,
    };
    let a = with_defaults(&REFERENCE_BOARD, ControllerConfig::default());
    let b = with_defaults(&REFERENCE_BOARD, odd);
    assert_eq!(a, b);
    assert_eq!(a, controller_config());
    assert!(piezo_drive::controller::Controller::new(a).is_ok());
}
