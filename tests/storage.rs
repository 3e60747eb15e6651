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
        |c| c.fine_gain = 2.0,
        |c| c.drive_freq_hz = 10_000.0,
        |c| c.preload_max_n = c.preload_min_n,
        |c| c.travel_max_nm = c.travel_min_nm,
        |c| c.encoder_nm_per_count = 0,
        |c| c.max_drive_v = 500.0,
    ];
    for (i, f) in cases.iter().enumerate() {
        let mut c = d;
        f(&mut c);
        assert_eq!(storage::validate(&c), Err(StorageError::OutOfRange), "case {i}");
        let rec = storage::encode(&c);
        assert_eq!(storage::decode(&rec, &d), Err(StorageError::OutOfRange), "case {i}");
    }
    // A non-0/1 bool byte is refused.
    let mut rec = storage::encode(&d);
    let ff = RECORD_LEN - 4 - 7 * 4 - 1;
    assert_eq!(rec[ff], 1);
    rec[ff] = 2;
    let crc = storage::crc32(&rec[..RECORD_LEN - 4]);
    rec[RECORD_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(storage::decode(&rec, &d), Err(StorageError::OutOfRange));
}

proptest! {
    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let d = controller_config();
        if let Ok(c) = storage::decode(&bytes, &d) {
            prop_assert!(storage::validate(&c).is_ok());
        }
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
        if let Ok(c) = storage::decode(&rec, &d) {
            prop_assert!(storage::validate(&c).is_ok());
            prop_assert_eq!(storage::encode(&c), rec);
        }
    }

    #[test]
    fn valid_configs_round_trip(kp in 0.0f32..1e4, gain in 0.0f32..=1.0, f in 500.0f32..=2200.0,
                                lo in -1_000_000_000i64..0, hi in 1i64..1_000_000_000, zero in any::<u16>()) {
        let d = controller_config();
        let mut c = d;
        c.kp_per_s = kp;
        c.fine_gain = gain;
        c.drive_freq_hz = f;
        c.travel_min_nm = lo;
        c.travel_max_nm = hi;
        c.preload.zero_word = zero;
        prop_assert_eq!(storage::decode(&storage::encode(&c), &d), Ok(c));
    }
}
