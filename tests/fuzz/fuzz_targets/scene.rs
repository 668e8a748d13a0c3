//! Any bytes through the whole path a scene takes before its first step
//! (`drape::jobs::check_untrusted`: read, validate, admit under the default limits, compile,
//! build the simulation). A refusal is a fine answer; a panic, a hang or an allocation beyond
//! libFuzzer's `-malloc_limit_mb` is a finding.

#![no_main]

use drape::jobs::{Limits, check_untrusted};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let _ = check_untrusted(bytes, &Limits::default());
});
