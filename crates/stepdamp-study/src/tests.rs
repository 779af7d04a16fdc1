use crate::run::Table;
use crate::spec::Study;
use crate::summary::percentile;
use std::path::Path;

fn study(extra: &str) -> Study {
    study_with("", extra)
}

fn study_with(top: &str, extra: &str) -> Study {
    let text = format!(
        "motor = \"patent-motor\"\nvariants = 8\nseed = 7\n{top}[sweep]\ncompensations = [\"patent\"]\norders = [4, 2]\npoints = 1\nduration_s = 0.4\n{extra}"
    );
    Study::from_toml_str(&text, "study.toml", Path::new(".")).unwrap()
}

const TOLERANCES: &str = "[plant]\nresistance_ohm = { scale = [0.9, 1.1] }\ninertia_kg_m2 = { scale = [0.8, 1.5] }\n\
                          detent_amplitude_nm = { scale = [0.8, 1.2] }\ndetent_phase_rad = { add = [-0.2, 0.2] }\n";

#[test]
fn a_table_does_not_depend_on_how_the_variants_are_split() {
    let s = study(TOLERANCES);
    let whole = s.run_range(0, 5, &|| {}).unwrap();
    let mut parts = s.run_range(0, 2, &|| {}).unwrap();
    parts.rows.extend(s.run_range(2, 5, &|| {}).unwrap().rows);
    assert_eq!(whole, parts);
    assert_eq!(whole.rows[3], s.run_variant(3).unwrap());
    // NaN-free here, so equality above compared every value.
    assert!(whole.rows.iter().flatten().all(|v| v.is_finite()));
}

#[test]
fn variants_are_drawn_within_their_distributions_and_differ() {
    let s = study(TOLERANCES);
    let n = &s.nominal.motor;
    let mut js = Vec::new();
    for i in 0..8 {
        let v = s.variant(i).unwrap();
        let m = &v.plant.motor;
        assert!((0.9 * n.resistance_ohm..=1.1 * n.resistance_ohm).contains(&m.resistance_ohm));
        assert!((0.8 * n.inertia_kg_m2..=1.5 * n.inertia_kg_m2).contains(&m.inertia_kg_m2));
        for (h, h0) in m.detent.iter().zip(&n.detent) {
            assert!((0.8 * h0.amplitude_nm..=1.2 * h0.amplitude_nm).contains(&h.amplitude_nm));
            assert!((h.phase_rad - h0.phase_rad).abs() <= 0.2);
        }
        assert_eq!(m.inductance_h, n.inductance_h, "not varied");
        // The nominal controller by default.
        assert_eq!(v.controller.motor, *n);
        js.push(m.inertia_kg_m2);
    }
    js.dedup();
    assert_eq!(js.len(), 8);
    // The same index draws the same variant, another seed another one.
    assert_eq!(s.variant(3).unwrap(), s.variant(3).unwrap());
    let mut other = study(TOLERANCES);
    other.spec.seed = 8;
    assert_ne!(other.variant(3).unwrap().plant.motor, s.variant(3).unwrap().plant.motor);
}

#[test]
fn the_controller_error_moves_the_controllers_model_only() {
    let s =
        study_with("controller = \"plant\"\n", "[controller_error]\ndetent_amplitude_nm = { scale = [1.5, 1.5] }\n");
    let v = s.variant(0).unwrap();
    for (c, p) in v.controller.motor.detent.iter().zip(&v.plant.motor.detent) {
        assert!((c.amplitude_nm - 1.5 * p.amplitude_nm).abs() < 1e-15);
    }
    assert!(s.columns().iter().any(|c| c == "controller_detent_k4_amplitude_nm"));
}

#[test]
fn compensation_with_the_true_model_reduces_the_nominal_motors_resonances() {
    let s = study("");
    let t = s.run_range(0, 1, &|| {}).unwrap();
    let col = |name: &str| t.columns.iter().position(|c| c == name).unwrap();
    let r4 = t.rows[0][col("reduction_open-loop_patent_k4")];
    let pp_off = t.rows[0][col("pp_open-loop_off_k4_rad_s")];
    let pp_on = t.rows[0][col("pp_open-loop_patent_k4_rad_s")];
    assert_eq!(r4, pp_off / pp_on);
    assert!(r4 > 3.0, "patent law at k=4 on the true model: {r4}");
}

#[test]
fn the_summary_counts_worse_and_holding_variants_and_lists_the_worst() {
    let s = study("[report]\nthreshold = 10.0\nworst = 2\n");
    let cols = s.columns();
    let (r4, r2) = (
        cols.iter().position(|c| c == "reduction_open-loop_patent_k4").unwrap(),
        cols.iter().position(|c| c == "reduction_open-loop_patent_k2").unwrap(),
    );
    let row = |i: f64, a: f64, b: f64| {
        let mut r = vec![0.0; cols.len()];
        r[0] = i;
        r[r4] = a;
        r[r2] = b;
        r
    };
    // Out of order on purpose; variant 2 has a NaN (both diverged) = 0.
    let t = Table {
        columns: cols.clone(),
        rows: vec![row(3.0, 20.0, 30.0), row(0.0, 12.0, 0.5), row(2.0, f64::NAN, 40.0), row(1.0, 50.0, 11.0)],
    };
    let sum = s.summarize(&t).unwrap();
    let p = &sum.pairs[0];
    assert_eq!((p.mode.as_str(), p.compensation.as_str()), ("open-loop", "patent"));
    assert_eq!(p.share_hold_all, 0.5);
    assert_eq!(p.share_worse_any, 0.5);
    assert_eq!(p.resonances[0].share_worse, 0.25);
    assert_eq!(p.resonances[1].min, 0.5);
    assert_eq!(p.worst.iter().map(|w| (w.variant, w.order)).collect::<Vec<_>>(), vec![(2, 4), (0, 2)]);
    assert!(sum.report().contains("holds ≥ 10x at every resonance in 50.0 % of variants"), "{}", sum.report());
    let mut dup = t.clone();
    dup.rows.push(row(3.0, 1.0, 1.0));
    assert!(s.summarize(&dup).unwrap_err().to_string().contains("twice"));
}

#[test]
fn percentiles_interpolate_between_order_statistics() {
    let x = [1.0, 2.0, 3.0, 4.0, 5.0];
    assert_eq!(percentile(&x, 50.0), 3.0);
    assert_eq!(percentile(&x, 0.0), 1.0);
    assert_eq!(percentile(&x, 100.0), 5.0);
    assert_eq!(percentile(&x, 12.5), 1.5);
}

#[test]
fn a_study_survives_its_json_round_trip() {
    let s = study(TOLERANCES);
    assert_eq!(Study::from_json(&s.to_json()).unwrap(), s);
}

#[test]
fn spec_errors_name_the_file_and_the_key() {
    let err = |text: &str| Study::from_toml_str(text, "s.toml", Path::new(".")).unwrap_err().to_string();
    let base = "motor = \"patent-motor\"\nvariants = 4\n";
    let e = err(&format!("{base}[plant]\nresistance = {{ scale = [0.9, 1.1] }}\n"));
    assert!(e.starts_with("s.toml: ") && e.contains("resistance"), "{e}");
    let e = err(&format!("{base}[plant]\ninertia_kg_m2 = {{ scale = [-1.0, 1.1] }}\n"));
    assert!(e.contains("plant.inertia_kg_m2") && e.contains("> 0"), "{e}");
    let e = err(&format!("{base}[plant]\ninertia_kg_m2 = {{ add = [1.0, 0.5] }}\n"));
    assert!(e.contains("lo ≤ hi"), "{e}");
    let e = err("motor = \"nope\"\nvariants = 4\n");
    assert!(e.contains("motor = 'nope'"), "{e}");
    let e = err("motor = \"patent-motor\"\nvariants = 0\n");
    assert!(e.contains("variants = 0"), "{e}");
    let e = err(&format!("{base}[sweep]\ncompensations = [\"off\"]\n"));
    assert!(e.contains("sweep.compensations"), "{e}");
    let e = err(&format!("{base}[sweep]\nmodes = [\"servo\"]\ncompensations = [\"estimated\"]\n"));
    assert!(e.contains("estimated"), "{e}");
    // Names are the core's (one definition): an unknown one is reported with the core's list.
    let e = err(&format!("{base}[sweep]\nmodes = [\"sideways\"]\n"));
    assert!(e.contains("sweep.modes: 'sideways': unknown mode: expected open-loop, servo"), "{e}");
    let e = err(&format!("{base}[sweep]\ncompensations = [\"off\", \"maybe\"]\n"));
    assert!(e.contains("sweep.compensations: 'maybe': unknown compensation: expected off, patent, estimated"), "{e}");
    // A study has no table file to replay.
    let e = err(&format!("{base}[sweep]\ncompensations = [\"table\"]\n"));
    assert!(e.contains("table"), "{e}");
    let e = err(&format!("{base}[controller_error]\nload_torque_nm = {{ uniform = [0.0, 0.1] }}\n"));
    assert!(e.contains("controller_error.load_torque_nm"), "{e}");
}

#[test]
fn a_variant_outside_the_physical_range_is_an_error_naming_it() {
    // Variant 0 is checked when the spec is read; a later one when it is run.
    let text = "motor = \"patent-motor\"\nvariants = 8\n[plant]\ncoulomb_friction_nm = { add = [-1.0, -1.0] }\n";
    let e = Study::from_toml_str(text, "s.toml", Path::new(".")).unwrap_err().to_string();
    assert!(e.starts_with("variant 0: ") && e.contains("coulomb_friction_nm"), "{e}");
    let mut s = study("");
    s.spec.plant.coulomb_friction_nm = Some(crate::Dist::Add([-1.0, -1.0]));
    let e = s.run_range(1, 3, &|| {}).unwrap_err().to_string();
    assert!(e.starts_with("variant ") && e.contains("coulomb_friction_nm"), "{e}");
}

#[test]
fn spec_errors_print_numbers_in_short_form() {
    let err = |text: &str| Study::from_toml_str(text, "s.toml", Path::new(".")).unwrap_err().to_string();
    let base = "motor = \"patent-motor\"\nvariants = 4\n";
    let e = err(&format!("{base}[plant]\ninertia_kg_m2 = {{ add = [1e300, 1e-300] }}\n"));
    assert!(e.contains("[1e300, 1e-300]") && e.len() < 200, "{e}");
    let e = err(&format!("{base}[sweep]\nduration_s = 1e-300\n"));
    assert!(e.contains("sweep.duration_s = 1e-300:"), "{e}");
}

#[test]
fn an_endless_spec_is_refused_after_the_spec_limit() {
    let e = Study::load(Path::new("/dev/zero")).unwrap_err().to_string();
    assert!(e.contains("/dev/zero") && e.contains(&crate::spec::MAX_SPEC_BYTES.to_string()), "{e}");
}

#[test]
fn a_study_from_json_is_held_to_the_size_bounds_of_a_spec_file() {
    let s = study("");
    assert_eq!(Study::from_json(&s.to_json()).unwrap().to_json(), s.to_json());
    let mut big = study("");
    big.spec.variants = 1_000_000_000_000_000;
    let e = Study::from_json(&big.to_json()).unwrap_err().to_string();
    assert!(e.contains("variants = 1000000000000000: must be in 1..=10000000"), "{e}");
    let mut wide = study("");
    wide.spec.sweep.points = 1_000_000_000_000;
    let e = Study::from_json(&wide.to_json()).unwrap_err().to_string();
    assert!(e.contains("sweep.points = 1000000000000: must be in 1..=50"), "{e}");
}

#[test]
fn a_study_range_stops_when_its_stop_check_says_so() {
    let s = study("");
    let e = s.run_range_until(0, 2, &|| {}, &|| true).unwrap_err().to_string();
    assert!(e.contains("stopped at t = 0 s"), "{e}");
}
