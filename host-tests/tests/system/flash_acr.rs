//! The flash accelerator's register value against the stock firmware's literal and RM0090's wait-state table,
//! and the read-back check against what embassy-stm32 0.6 leaves behind (latency only: caches off).

use cfnav::system::flash_acr::{AcrFindings, cache_reset_word, check_acr, expected_acr, wait_states};

/// CMSIS `stm32f4xx.h` bit values as the stock `SystemInit` uses them (bitcraze crazyflie-firmware,
/// `system_stm32f4xx.c`: `FLASH->ACR = FLASH_ACR_PRFTEN | FLASH_ACR_ICEN | FLASH_ACR_DCEN | FLASH_ACR_LATENCY_5WS`).
const CMSIS_PRFTEN: u32 = 0x0000_0100;
const CMSIS_ICEN: u32 = 0x0000_0200;
const CMSIS_DCEN: u32 = 0x0000_0400;
const CMSIS_ICRST: u32 = 0x0000_0800;
const CMSIS_DCRST: u32 = 0x0000_1000;
const CMSIS_LATENCY_5WS: u32 = 0x0000_0005;

#[test]
fn at_168_mhz_the_value_is_stocks() {
    assert_eq!(
        expected_acr(168_000_000),
        Some(CMSIS_PRFTEN | CMSIS_ICEN | CMSIS_DCEN | CMSIS_LATENCY_5WS)
    );
    assert_eq!(
        check_acr(CMSIS_PRFTEN | CMSIS_ICEN | CMSIS_DCEN | CMSIS_LATENCY_5WS, 168_000_000),
        Some(AcrFindings::default())
    );
}

#[test]
fn the_reset_word_disables_the_caches_it_resets() {
    let w = cache_reset_word(168_000_000).unwrap();
    assert_eq!(w, CMSIS_ICRST | CMSIS_DCRST | CMSIS_LATENCY_5WS);
    // RM0090 §3.9.1: ICRST/DCRST may only be written while ICEN/DCEN are 0; the latency must not drop.
    assert_eq!(w & (CMSIS_ICEN | CMSIS_DCEN), 0);
    assert!(!check_acr(w, 168_000_000).unwrap().is_ok());
}

#[test]
fn what_embassy_leaves_is_reported_as_caches_off() {
    // embassy-stm32 0.6 rcc/f247.rs: latency = (hclk - 1) / 30 MHz, written alone.
    let embassy = (168_000_000u32 - 1) / 30_000_000;
    let f = check_acr(embassy, 168_000_000).unwrap();
    assert_eq!(
        f,
        AcrFindings {
            wrong_latency: None,
            prefetch_off: true,
            icache_off: true,
            dcache_off: true,
            reset_held: false,
        }
    );
    assert!(!f.is_ok());
    // One missing bit is found alone; a wrong latency is reported with the value read.
    let all = expected_acr(168_000_000).unwrap();
    assert!(check_acr(all & !CMSIS_DCEN, 168_000_000).unwrap().dcache_off);
    assert!(!check_acr(all & !CMSIS_DCEN, 168_000_000).unwrap().icache_off);
    assert_eq!(check_acr((all & !7) | 4, 168_000_000).unwrap().wrong_latency, Some(4));
    assert!(check_acr(all | CMSIS_DCRST, 168_000_000).unwrap().reset_held);
}

#[test]
fn wait_states_follow_rm0090_table_10() {
    // RM0090 table 10, 2.7–3.6 V: (upper HCLK bound in MHz, wait states).
    let table = [(30u32, 0u32), (60, 1), (90, 2), (120, 3), (150, 4), (168, 5)];
    let mut lower = 0u32;
    for (upper_mhz, ws) in table {
        let upper = upper_mhz * 1_000_000;
        for hz in [lower + 1, (lower + upper) / 2, upper] {
            assert_eq!(wait_states(hz), Some(ws), "{hz} Hz");
            assert_eq!(expected_acr(hz).unwrap() & 7, ws);
        }
        lower = upper;
    }
    assert_eq!(wait_states(0), None);
    assert_eq!(wait_states(168_000_001), None);
    assert_eq!(expected_acr(200_000_000), None);
    assert_eq!(check_acr(0, 0), None);
}
