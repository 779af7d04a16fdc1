//! Drawing variants and running them: one row of the results table per variant.
//!
//! Variant `i` draws its parameters from a ChaCha8 generator seeded with
//! `derived_seed(study seed, i)`, in the fixed order of [`Variation::scalar_entries`],
//! then each detent harmonic (amplitude, phase) in the profile's order, then the load;
//! the controller's error is drawn after, in the same order. So a variant is the same
//! whoever runs it, alone or in any chunk.

use crate::spec::{ControllerModel, Study, StudyError, Variation};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use stepdamp_sim::profile::ProfileData;
use stepdamp_sim::profile::name::derived_name;
use stepdamp_sim::sweep::derived_seed;
use stepdamp_sim::{Profile, RunSpec, SimOptions, SweepRow, SweepSpec, linear_grid, sweep_until};

/// One drawn motor variant.
#[derive(Clone, Debug, PartialEq)]
pub struct Variant {
    /// Index in the study.
    pub index: u64,
    /// The simulated motor.
    pub plant: Profile,
    /// The controller's model of it.
    pub controller: Profile,
    /// Load torque in N·m.
    pub load_torque_nm: f64,
}

/// The results table: one row per variant, columns named by [`Study::columns`]. Every
/// value is an `f64` (the variant index, exact below 2⁵³, and 0/1 flags included).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Table {
    /// Column names.
    pub columns: Vec<String>,
    /// Rows, in variant order.
    pub rows: Vec<Vec<f64>>,
}

fn apply(v: &Variation, p: &mut ProfileData, rng: &mut ChaCha8Rng) -> f64 {
    let m = &mut p.motor;
    let slots: [&mut f64; 6] = [
        &mut m.resistance_ohm,
        &mut m.inductance_h,
        &mut m.km_nm_per_a,
        &mut m.inertia_kg_m2,
        &mut m.coulomb_friction_nm,
        &mut m.viscous_nm_s_per_rad,
    ];
    for ((_, d), slot) in v.scalar_entries().into_iter().zip(slots) {
        if let Some(d) = d {
            *slot = d.apply(*slot, rng.random::<f64>());
        }
    }
    for h in &mut m.detent {
        if let Some(d) = v.detent_amplitude_nm {
            h.amplitude_nm = d.apply(h.amplitude_nm, rng.random::<f64>());
        }
        if let Some(d) = v.detent_phase_rad {
            h.phase_rad = d.apply(h.phase_rad, rng.random::<f64>());
        }
    }
    v.load_torque_nm.map_or(0.0, |d| d.apply(0.0, rng.random::<f64>()))
}

/// Ratio of the peak-to-peak velocity error without compensation to that with it
/// (`off / on`; > 1 means compensation helps). A diverged run (NaN) counts as an infinite
/// error: a diverged compensated run gives 0, a diverged reference alone gives ∞, both NaN.
pub fn reduction(off_pp: f64, on_pp: f64) -> f64 {
    let h = |v: f64| if v.is_nan() { f64::INFINITY } else { v };
    h(off_pp) / h(on_pp)
}

/// Highest peak-to-peak velocity error among `rows` (NaN, a diverged run, is the highest).
pub fn peak_pp(rows: &[&SweepRow]) -> f64 {
    if rows.iter().any(|r| r.vel_err_pp_rad_s.is_nan()) {
        return f64::NAN;
    }
    rows.iter().map(|r| r.vel_err_pp_rad_s).fold(f64::NEG_INFINITY, f64::max)
}

impl Study {
    /// Draws variant `index`.
    pub fn variant(&self, index: u64) -> Result<Variant, StudyError> {
        let mut rng = ChaCha8Rng::seed_from_u64(derived_seed(self.spec.seed, index));
        let mut plant = self.nominal.to_data();
        let load = apply(&self.spec.plant, &mut plant, &mut rng);
        let mut controller = match self.spec.controller {
            ControllerModel::Nominal => self.nominal.to_data(),
            ControllerModel::Plant => plant.clone(),
        };
        apply(&self.spec.controller_error, &mut controller, &mut rng);
        plant.name = derived_name(&self.nominal.name, &format!(" variant {index}"));
        controller.name = derived_name(&self.nominal.name, &format!(" controller model {index}"));
        let bad = |e: stepdamp_sim::ProfileError| StudyError::Variant { index, message: e.to_string() };
        let plant = plant.validate("plant").map_err(bad)?;
        let controller = controller.validate("controller").map_err(bad)?;
        if !(load.is_finite() && load >= 0.0) {
            return Err(StudyError::Variant {
                index,
                message: format!("load_torque_nm = {}: must be ≥ 0 N·m", stepdamp_core::limits::Num(load)),
            });
        }
        Ok(Variant { index, plant, controller, load_torque_nm: load })
    }

    /// The speeds of a variant: `points` per resonance order, over ±span of the variant's
    /// own resonance speed `ω_n/(k·Nr)`, order by order.
    pub fn speeds(&self, v: &Variant) -> Vec<f64> {
        let s = &self.spec.sweep;
        let mut out = Vec::new();
        for &k in &self.orders {
            let w = v.plant.resonance_speed_rad_s(k);
            // `points` is in 1..=50 (`SweepSection::check`, also for a study from JSON),
            // far below the grid's bound.
            out.extend(linear_grid(w * (1.0 - s.span), w * (1.0 + s.span), s.points).expect("sweep.points ≤ 50"));
            if s.points == 1 {
                *out.last_mut().expect("one point pushed") = w;
            }
        }
        out
    }

    /// The sweep a variant runs (the CLI's run shape, [`RunSpec::for_duration`]); its noise
    /// seed derives from the variant's.
    pub fn sweep_spec(&self, v: &Variant) -> SweepSpec {
        let s = &self.spec.sweep;
        SweepSpec {
            speeds_rad_s: self.speeds(v),
            modes: self.modes(),
            compensations: self.compensations(),
            run: RunSpec::for_duration(1.0, s.duration_s),
            options: SimOptions {
                substeps: s.substeps,
                current_noise_a: s.current_noise_a,
                seed: derived_seed(derived_seed(self.spec.seed, v.index), u64::MAX),
                load_torque_nm: v.load_torque_nm,
                ..SimOptions::default()
            },
            table: None,
        }
    }

    /// The (mode, compensation) pairs of the table, by name, in order.
    pub fn pairs(&self) -> Vec<(&'static str, &'static str)> {
        let probe = SweepSpec {
            speeds_rad_s: vec![],
            modes: self.modes(),
            compensations: self.compensations(),
            run: RunSpec::at(1.0),
            options: SimOptions::default(),
            table: None,
        };
        probe.pairs().into_iter().map(|(m, c)| (m.name(), c.name())).collect()
    }

    /// Parameter columns: the plant's, then the controller's where it has its own error.
    fn param_columns(&self) -> Vec<String> {
        let mut cols: Vec<String> = Vec::new();
        let mut add = |prefix: &str| {
            for (k, _) in Variation::default().scalar_entries() {
                cols.push(format!("{prefix}{k}"));
            }
            for h in &self.nominal.motor.detent {
                cols.push(format!("{prefix}detent_k{}_amplitude_nm", h.order));
                cols.push(format!("{prefix}detent_k{}_phase_rad", h.order));
            }
        };
        add("");
        if !self.spec.controller_error.is_empty() || self.spec.controller == ControllerModel::Plant {
            add("controller_");
        }
        cols.push("load_torque_nm".into());
        cols
    }

    /// Columns of the results table: `variant`, the parameters, each resonance's speed
    /// `resonance_k{k}_rad_s`, then per (mode, compensation) the peak-to-peak velocity error near
    /// each resonance `pp_{mode}_{comp}_k{k}_rad_s`, the number of runs that lost sync
    /// `lost_sync_{mode}_{comp}`, and for compensations other than off the reduction
    /// `reduction_{mode}_{comp}_k{k}` ([`reduction`]).
    pub fn columns(&self) -> Vec<String> {
        let mut cols = vec!["variant".to_string()];
        cols.extend(self.param_columns());
        for &k in &self.orders {
            cols.push(format!("resonance_k{k}_rad_s"));
        }
        for (m, c) in self.pairs() {
            for &k in &self.orders {
                cols.push(format!("pp_{m}_{c}_k{k}_rad_s"));
            }
            cols.push(format!("lost_sync_{m}_{c}"));
        }
        for (m, c) in self.pairs().into_iter().filter(|p| p.1 != "off") {
            for &k in &self.orders {
                cols.push(format!("reduction_{m}_{c}_k{k}"));
            }
        }
        cols
    }

    fn params(&self, v: &Variant) -> Vec<f64> {
        let mut out = Vec::new();
        let mut add = |p: &Profile| {
            let m = &p.motor;
            out.extend([
                m.resistance_ohm,
                m.inductance_h,
                m.km_nm_per_a,
                m.inertia_kg_m2,
                m.coulomb_friction_nm,
                m.viscous_nm_s_per_rad,
            ]);
            for h in &m.detent {
                out.extend([h.amplitude_nm, h.phase_rad]);
            }
        };
        add(&v.plant);
        if !self.spec.controller_error.is_empty() || self.spec.controller == ControllerModel::Plant {
            add(&v.controller);
        }
        out.push(v.load_torque_nm);
        out
    }

    /// Runs variant `index` and returns its row (in [`Study::columns`] order).
    pub fn run_variant(&self, index: u64) -> Result<Vec<f64>, StudyError> {
        self.run_variant_until(index, &|| false)
    }

    /// [`Study::run_variant`] that stops with an error once `stop` returns true (asked
    /// before every control period, [`stepdamp_sim::sweep_until`]).
    fn run_variant_until(&self, index: u64, stop: &(dyn Fn() -> bool + Sync)) -> Result<Vec<f64>, StudyError> {
        let v = self.variant(index)?;
        let spec = self.sweep_spec(&v);
        let rows = sweep_until(&v.plant, &v.controller, &spec, &|| {}, stop)
            .map_err(|e| StudyError::Variant { index, message: e.to_string() })?;
        let mut out = vec![index as f64];
        out.extend(self.params(&v));
        for &k in &self.orders {
            out.push(v.plant.resonance_speed_rad_s(k));
        }
        let n = self.spec.sweep.points;
        let pairs = self.pairs();
        // Rows come by pair, then speed in `speeds` order: group g of each pair is order g.
        let per_pair = self.orders.len() * n;
        let peak = |pair: usize, g: usize| {
            let chunk: Vec<&SweepRow> = rows[pair * per_pair + g * n..pair * per_pair + (g + 1) * n].iter().collect();
            peak_pp(&chunk)
        };
        for (p, _) in pairs.iter().enumerate() {
            for g in 0..self.orders.len() {
                out.push(peak(p, g));
            }
            let lost = rows[p * per_pair..(p + 1) * per_pair].iter().filter(|r| r.lost_sync).count();
            out.push(lost as f64);
        }
        for (p, &(m, c)) in pairs.iter().enumerate() {
            if c == "off" {
                continue;
            }
            let off = pairs.iter().position(|&(m2, c2)| m2 == m && c2 == "off").expect("off is always run");
            for g in 0..self.orders.len() {
                out.push(reduction(peak(off, g), peak(p, g)));
            }
        }
        Ok(out)
    }

    /// Runs variants `from..to` in parallel (rayon) and returns their rows in index order;
    /// `tick` is called once per finished variant (from any thread).
    pub fn run_range(&self, from: u64, to: u64, tick: &(dyn Fn() + Sync)) -> Result<Table, StudyError> {
        self.run_range_until(from, to, tick, &|| false)
    }

    /// [`Study::run_range`] with a cancellation hook: `stop` is asked before every control
    /// period (from any thread); once it returns true the runs in progress end within a
    /// period and the call returns an error (e.g. for Ctrl-C in the Python binding).
    pub fn run_range_until(
        &self,
        from: u64,
        to: u64,
        tick: &(dyn Fn() + Sync),
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Result<Table, StudyError> {
        if from > to || to > self.spec.variants {
            return Err(StudyError::Table(format!(
                "variants {from}..{to}: outside the study's 0..{}",
                self.spec.variants
            )));
        }
        let rows = (from..to)
            .into_par_iter()
            .map(|i| {
                let r = self.run_variant_until(i, stop);
                tick();
                r
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Table { columns: self.columns(), rows })
    }
}
