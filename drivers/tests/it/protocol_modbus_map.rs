//! Chamber register maps: presets, word encodings, EEPROM protection, config parsing.
#![allow(clippy::unwrap_used)]

use bench_drivers::protocol::modbus_map::{
    Decimals, Preset, RegisterMap, RegisterWrite, ValueEncoding, WordOrder,
};
use proptest::prelude::*;

#[test]
fn presets_match_device_facts() {
    let f4 = RegisterMap::preset(Preset::WatlowF4);
    assert_eq!((f4.process_value, f4.set_point, f4.decimals_register()), (100, 300, Some(606)));
    assert_eq!(f4.process_value_read(), (100, 1));
    let f4t = RegisterMap::preset(Preset::WatlowF4T);
    assert_eq!((f4t.process_value, f4t.set_point, f4t.working_set_point), (2820, 2782, Some(2810)));
    assert_eq!(f4t.process_value_read(), (2820, 2));
    let e = RegisterMap::preset(Preset::Eurotherm3216);
    assert_eq!(
        (e.process_value, e.set_point, e.working_set_point, e.ramp_rate),
        (1, 26, Some(5), Some(35))
    );
    assert_eq!(e.on_connect, vec![RegisterWrite { register: 276, value: 1 }]);
    for p in [Preset::WatlowF4, Preset::WatlowF4T, Preset::Eurotherm3216] {
        RegisterMap::preset(p).validate().unwrap();
    }
}

#[test]
fn eurotherm_never_writes_eeprom_set_point() {
    let e = RegisterMap::preset(Preset::Eurotherm3216);
    let (reg, words) = e.set_point_writes(-40.0, 1).unwrap();
    assert_eq!(reg, 26);
    assert_eq!(words, vec![(-400i16) as u16]);
    assert!(e.eeprom_registers.contains(&2));
    // A map pointed at the EEPROM target set point is refused.
    let mut bad = e.clone();
    bad.set_point = 2;
    assert!(bad.validate().is_err());
    assert!(bad.set_point_writes(20.0, 1).is_err());
}

#[test]
fn int16_with_implied_decimals() {
    let enc = ValueEncoding::Int16 { decimals: Decimals::Register(606) };
    assert_eq!(enc.encode(-40.0, 1).unwrap(), vec![0xFE70]); // -400
    assert_eq!(enc.encode(23.46, 2).unwrap(), vec![2346]);
    assert_eq!(enc.encode(60.04, 1).unwrap(), vec![600]); // rounded to the display resolution
    assert_eq!(enc.decode(&[0xFE70], 1).unwrap(), -40.0);
    assert_eq!(enc.decode(&[250], 0).unwrap(), 250.0);
    assert!(enc.encode(400.0, 2).is_err()); // 40000 > i16::MAX
    assert!(enc.encode(f64::NAN, 1).is_err());
    assert!(enc.decode(&[1, 2], 1).is_err());
    assert!(enc.decode(&[1], 9).is_err());
}

#[test]
fn float32_word_orders() {
    // 25.5 = 0x41CC0000.
    let low = ValueEncoding::Float32 { word_order: WordOrder::LowWordFirst };
    let high = ValueEncoding::Float32 { word_order: WordOrder::HighWordFirst };
    assert_eq!(low.encode(25.5, 0).unwrap(), vec![0x0000, 0x41CC]);
    assert_eq!(high.encode(25.5, 0).unwrap(), vec![0x41CC, 0x0000]);
    // -40.125 = 0xC2208000.
    assert_eq!(low.decode(&[0x8000, 0xC220], 0).unwrap(), -40.125);
    assert_eq!(high.decode(&[0xC220, 0x8000], 0).unwrap(), -40.125);
    assert!(low.decode(&[0x0000, 0x7FC0], 0).is_err(), "NaN");
    assert!(low.decode(&[0x0000], 0).is_err());
    assert!(low.encode(1e39, 0).is_err());
}

#[test]
fn map_from_bench_config_toml() {
    let text = r#"
        model = "Lab chamber"
        process_value = 100
        set_point = 300
        encoding = { type = "int16", decimals = { register = 606 } }
        eeprom_registers = [7]
    "#;
    let m: RegisterMap = toml::from_str(text).unwrap();
    assert_eq!(m.encoding, ValueEncoding::Int16 { decimals: Decimals::Register(606) });
    assert_eq!(m.eeprom_registers, vec![7]);
    let f: RegisterMap = toml::from_str(
        r#"
        model = "F4T loop 2"
        process_value = 2980
        set_point = 2942
        encoding = { type = "float32", word_order = "low_word_first" }
    "#,
    )
    .unwrap();
    assert_eq!(f.encoding, ValueEncoding::Float32 { word_order: WordOrder::LowWordFirst });
    let p: Preset = toml::from_str::<toml::Table>("p = \"eurotherm_3216\"").unwrap()["p"]
        .clone()
        .try_into()
        .unwrap();
    assert_eq!(p, Preset::Eurotherm3216);
    assert!(toml::from_str::<RegisterMap>("model = \"x\"\nprocess_value = 1\nset_point = 2\nencoding = { type = \"int16\", decimals = { fixed = 1 } }\nbogus = 1").is_err());
}

proptest! {
    #[test]
    fn int16_roundtrip(raw in any::<i16>(), decimals in 0u8..=4) {
        let enc = ValueEncoding::Int16 { decimals: Decimals::Fixed(decimals) };
        let v = enc.decode(&[raw as u16], decimals).unwrap();
        prop_assert_eq!(enc.encode(v, decimals).unwrap(), vec![raw as u16]);
    }

    #[test]
    fn float32_roundtrip(v in any::<f32>().prop_filter("finite", |v| v.is_finite()), low in any::<bool>()) {
        let word_order = if low { WordOrder::LowWordFirst } else { WordOrder::HighWordFirst };
        let enc = ValueEncoding::Float32 { word_order };
        let words = enc.encode(f64::from(v), 0).unwrap();
        prop_assert_eq!(enc.decode(&words, 0).unwrap(), f64::from(v));
    }
}
