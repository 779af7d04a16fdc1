//! Issue 14's done-when on `patent-motor`: the drives' laws against the patent's, measured
//! on the simulator at each resonance (largest p-p velocity error near `ω_n/(k·Nr)`).

use stepdamp_core::Compensation;
use stepdamp_export::{Correction, predict, prusa, tmc};
use stepdamp_sim::Profile;

fn setup() -> (Profile, Correction) {
    let p = Profile::preset("patent-motor").unwrap();
    let c = Correction::from_profile(&p, None).unwrap();
    (p, c)
}

#[test]
fn drive_laws_reduce_each_resonance_like_the_patent_law() {
    let (p, c) = setup();
    let prusa_table = prusa::fit(&c, prusa::Firmware::V6_3_1).unwrap().correction.table();
    let comps = vec![
        ("patent".to_string(), predict::config(&p, Compensation::Patent, None).unwrap()),
        ("angle".to_string(), predict::config(&p, Compensation::Angle, None).unwrap()),
        ("prusa table".to_string(), predict::config(&p, Compensation::Table, Some(&prusa_table)).unwrap()),
    ];
    let pr = predict::predict(&p, &comps, 1.0).unwrap();
    for x in &pr {
        eprint!("{x}");
    }
    let (patent, angle, table) = (&pr[0].rows, &pr[1].rows, &pr[2].rows);
    for i in 0..patent.len() {
        let (dp, da, dt) = (patent[i].reduction_db(), angle[i].reduction_db(), table[i].reduction_db());
        eprintln!("order {}: patent {dp:.1} dB, angle {da:.1} dB, prusa table {dt:.1} dB", patent[i].order);
        // Within a factor 2 of the patent law's reduction (as a ratio of p-p errors: dB/2).
        assert!(
            da >= dp - 20.0 * 2f64.log10() && da > 0.0,
            "angle at order {}: {da:.1} vs patent {dp:.1} dB",
            patent[i].order
        );
        assert!(dt >= 0.8 * da, "prusa table at order {}: {dt:.1} dB vs angle {da:.1} dB", patent[i].order);
    }
}

#[test]
fn tmc_table_reduces_the_first_resonance_as_its_report_predicts() {
    let (p, c) = setup();
    let e = tmc::export(&c).unwrap();
    eprint!("{e}");
    let o4 = e.coverage.iter().find(|o| o.order == 4).unwrap();
    assert!(e.coverage.iter().filter(|o| o.order < 4).all(|o| !o.expressible));
    assert!(o4.expressible && o4.reduction_db() > 20.0, "{o4:?}");
    // The report's prediction: the angle law carrying exactly the covered part of the model
    // (order 4's sine part), on the real motor whose orders 2 and 1 still ripple.
    let covered = tmc::covered_profile(&p).unwrap();
    let comps = vec![
        ("tmc table".to_string(), predict::config(&p, Compensation::Table, Some(&tmc::table(&e.registers))).unwrap()),
        ("covered part".to_string(), predict::config(&covered, Compensation::Angle, None).unwrap()),
    ];
    let pr = predict::predict(&p, &comps, 1.0).unwrap();
    eprint!("{}{}", pr[0], pr[1]);
    let first = |i: usize| pr[i].rows.iter().find(|r| r.order == 4).unwrap().reduction_db();
    let (got, want) = (first(0), first(1));
    eprintln!("order 4: table replay {got:.1} dB, report {want:.1} dB");
    assert!((got - want).abs() <= 0.2 * want.abs(), "{got:.1} dB vs predicted {want:.1} dB");
}
