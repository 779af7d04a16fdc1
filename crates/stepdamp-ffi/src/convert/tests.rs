use super::*;

const MODES: [Mode; 2] = [Mode::OpenLoop, Mode::Servo];
const COMPENSATIONS: [Compensation; 3] = [Compensation::Off, Compensation::Patent, Compensation::Estimated];

#[test]
fn patent_motor_in_c_layout_converts_back_to_the_cores_reference_params() {
    for mode in MODES {
        for comp in COMPENSATIONS {
            let c = patent_motor_c(mode_to_c(mode), compensation_to_c(comp)).unwrap();
            assert_eq!(c.motor.detent_count as usize, PATENT_MOTOR_DETENT.len());
            // SAFETY-free copy of the static table the pointer refers to.
            let harmonics: &[sd_harmonic] = &PATENT_DETENT_C;
            assert_eq!(c.motor.detent, harmonics.as_ptr());
            let mut tables = [[Harmonic::default(); SD_MAX_HARMONICS as usize]; 3];
            let back = params_from_c(&c, [harmonics, &[], &[]], &mut tables).unwrap();
            assert_eq!(back, Params::patent_motor(mode, comp));
        }
    }
}

#[test]
fn out_of_range_enum_integers_are_statuses() {
    assert_eq!(patent_motor_c(2, SD_COMPENSATION_OFF).unwrap_err(), SD_ERR_INVALID_MODE);
    assert_eq!(patent_motor_c(SD_MODE_SERVO, SD_COMPENSATION_TABLE + 1).unwrap_err(), SD_ERR_INVALID_COMPENSATION);
    let mut c = patent_motor_c(SD_MODE_SERVO, SD_COMPENSATION_OFF).unwrap();
    c.drive.topology = 7;
    let mut tables = [[Harmonic::default(); SD_MAX_HARMONICS as usize]; 3];
    assert_eq!(params_from_c(&c, [&[], &[], &[]], &mut tables).unwrap_err(), SD_ERR_INVALID_TOPOLOGY);
}

#[test]
fn every_status_code_is_distinct_and_has_its_own_text() {
    for (i, (code, text)) in STATUS_TEXTS.iter().enumerate() {
        assert_eq!(*code, i as sd_status, "codes are 0..N in order");
        assert_eq!(status_text(*code), *text);
        for (other, other_text) in &STATUS_TEXTS[..i] {
            assert_ne!(code, other);
            assert_ne!(text, other_text);
        }
    }
    assert_eq!(status_text(-1), c"unknown status");
    assert_eq!(status_text(STATUS_TEXTS.len() as sd_status), c"unknown status");
}
