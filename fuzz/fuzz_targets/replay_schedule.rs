//! Any bytes as a file to replay: a capture, or (first byte odd) an MCAP recording whose records
//! are the rest. `hilrig replay` reads recordings cut off by a crash, so damaged input must end in
//! a schedule, a schedule with the damage named, or an error; never a panic.
#![no_main]
use hilrig::replay::schedule;
use libfuzzer_sys::fuzz_target;

/// The MCAP magic, so that the fuzzer spends its time inside the recording's records.
const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

fuzz_target!(|data: &[u8]| {
    let mcap = data.first().is_some_and(|b| b % 2 == 1);
    let bytes = if mcap {
        [MCAP_MAGIC, &data[1..]].concat()
    } else {
        data.to_vec()
    };
    if let Ok((items, _)) = schedule(bytes, 2368, 8308) {
        // A recording's schedule is in log-time order (a capture's is in file order).
        if mcap {
            assert!(items.windows(2).all(|w| w[0].time <= w[1].time));
        }
    }
});
