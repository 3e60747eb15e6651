//! The linker memory map is the STM32G474RE's (RM0440 / datasheet: 512 KiB flash at 0x0800_0000,
//! 128 KiB SRAM at 0x2000_0000), and it is the one the build uses.

fn region(text: &str, name: &str) -> (u64, u64) {
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with(name) && l.contains("ORIGIN"))
        .unwrap_or_else(|| panic!("no {name} region in memory.x"));
    let origin = line.split("ORIGIN").nth(1).and_then(|s| s.split('=').nth(1)).unwrap();
    let origin = origin.split(',').next().unwrap().trim().trim_start_matches("0x");
    let length = line.split("LENGTH").nth(1).and_then(|s| s.split('=').nth(1)).unwrap().trim();
    let kib: u64 = length.trim_end_matches('K').parse().unwrap();
    (u64::from_str_radix(origin, 16).unwrap(), kib * 1024)
}

#[test]
fn memory_x_is_the_stm32g474re() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/memory.x")).unwrap();
    assert_eq!(region(&text, "FLASH"), (0x0800_0000, 512 * 1024));
    assert_eq!(region(&text, "RAM"), (0x2000_0000, 128 * 1024));
    // build.rs puts this very file on the linker path, and nothing else provides one.
    let build = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/build.rs")).unwrap();
    assert!(build.contains("\"memory.x\""));
    let manifest = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/Cargo.toml")).unwrap();
    assert!(!manifest.contains("memory-x"), "embassy's memory-x feature would supply a second memory.x");
}
