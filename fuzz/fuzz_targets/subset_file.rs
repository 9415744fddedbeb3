#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    oocfmt_fuzz::subset::subset_file(data);
});
