//! Stiff and extreme scenes, in process: every case of the stability study
//! (at its smoke size) keeps values and derivatives finite, forward mode
//! equal to finite differences and reverse mode, and energy balanced; every
//! invalid scene is rejected with a message naming the field.

use dualphoton::eval::stability::{cases, check_case, check_invalid, invalid_cases, Settings};

#[test]
fn every_extreme_case_passes() {
    let settings = Settings::new(true, 0);
    let cases = cases(&settings);
    assert!(cases.len() >= 20);
    for case in &cases {
        let r = check_case(case, &settings);
        assert!(r.values_finite == Some(true), "{}: image not finite or negative", r.case);
        assert!(r.derivatives_finite == Some(true), "{}: derivative not finite", r.case);
        assert!(r.passed, "{}: {}", r.case, r.note);
    }
}

#[test]
fn every_invalid_scene_is_rejected_naming_the_field() {
    let scratch = std::env::temp_dir().join(format!("dualphoton-extremes-{}", std::process::id()));
    for case in invalid_cases(&Settings::new(true, 0)) {
        let r = check_invalid(&case, &scratch);
        assert!(r.passed, "{}: {}", r.case, r.note);
        assert!(r.note.contains(case.field), "{}: {}", r.case, r.note);
    }
}
