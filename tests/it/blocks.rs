//! The SPM's whole-block kernel against the per-sample path it replaces: the same outputs,
//! sensitivities and initial-state sensitivities to the last bit, for both holds, with the
//! inverter's `v_dt`, with restarts (k-step prediction) and over several blocks; and the
//! normal equations of a problem built on either.

use greybox::Experiment;
use greybox::drive::{DriveConfig, SPM_MOTOR, scenario, simulate_drive};
use greybox::estimate::NormalEquations;
use greybox::estimate::{NominalScaling, PemProblem, ProblemOptions};
use greybox::model::{GreyBoxModel, Parameter, Prepared, Sensitivities, Signal};
use greybox::pmsm::{InverterModel, PmsmSetup, PmsmSpm, VoltageHold, VoltageInput};
use greybox::simulate::{SimOptions, visit_sensitivities};

/// A model that hides the block kernel of the model it wraps: the per-sample path.
struct PerSample<M>(M);

impl<M: GreyBoxModel> GreyBoxModel for PerSample<M> {
    type Inputs = M::Inputs;
    type Coefficients = M::Coefficients;
    fn n_states(&self) -> usize {
        self.0.n_states()
    }
    fn outputs(&self) -> Vec<Signal> {
        self.0.outputs()
    }
    fn input_channels(&self) -> Vec<String> {
        self.0.input_channels()
    }
    fn parameters(&self) -> &[Parameter] {
        self.0.parameters()
    }
    fn prepare(&self, e: &Experiment) -> greybox::Result<M::Inputs> {
        self.0.prepare(e)
    }
    fn coefficients(&self, th: &[f64], inp: &M::Inputs) -> greybox::Result<M::Coefficients> {
        self.0.coefficients(th, inp)
    }
    fn step(&self, c: &M::Coefficients, inp: &M::Inputs, k: usize, x: &[f64], xn: &mut [f64]) {
        self.0.step(c, inp, k, x, xn)
    }
    fn output(&self, c: &M::Coefficients, inp: &M::Inputs, k: usize, x: &[f64], y: &mut [f64]) {
        self.0.output(c, inp, k, x, y)
    }
    fn sensitivities(&self) -> Option<&dyn Sensitivities<M::Inputs, M::Coefficients>> {
        self.0.sensitivities()
    }
    fn step_state_derivative(
        &self,
        c: &M::Coefficients,
        inp: &M::Inputs,
        k: usize,
        x: &[f64],
        v: &[f64],
        out: &mut [f64],
    ) {
        self.0.step_state_derivative(c, inp, k, x, v, out)
    }
    fn output_state_derivative(
        &self,
        c: &M::Coefficients,
        inp: &M::Inputs,
        k: usize,
        x: &[f64],
        v: &[f64],
        out: &mut [f64],
    ) {
        self.0.output_state_derivative(c, inp, k, x, v, out)
    }
}

/// 5 000 samples (twenty blocks, the last one short) of the exp3 moves with a 6 V dead time.
fn log() -> Experiment {
    let mut cfg = DriveConfig { duration: 0.4999, ..scenario("exp3", SPM_MOTOR).unwrap() };
    cfg.inverter.v_dt = 6.0;
    simulate_drive(&cfg).unwrap().experiment
}

/// Every `(k, ŷ, ∂ŷ/∂θ, ∂ŷ/∂x₀)` of a run.
type Run = Vec<(usize, Vec<f64>, Vec<f64>, Vec<f64>)>;

fn run<M: GreyBoxModel>(m: &M, e: &Experiment, theta: &[f64], horizon: Option<usize>) -> Run {
    let prep = Prepared::new(m, e).unwrap();
    let mut out = Vec::new();
    let opts = SimOptions { horizon, x0_sensitivity: true, ..Default::default() };
    visit_sensitivities(m, &prep, theta, &opts, |k, y, dy, dy0| {
        out.push((k, y.to_vec(), dy.to_vec(), dy0.to_vec()))
    })
    .unwrap();
    out
}

/// The normal equations at `theta` with the initial state estimated.
fn normal_equations<M: GreyBoxModel>(m: &M, e: &Experiment, theta: &[f64]) -> NormalEquations {
    let opts = ProblemOptions { estimate_x0: true, ..Default::default() };
    let data = vec![(Prepared::new(m, e).unwrap(), None)];
    let pb = PemProblem::new(m, data, theta, &NominalScaling, &opts).unwrap();
    pb.normal_equations(&pb.start_vector(theta)).unwrap()
}

#[test]
fn the_spm_block_kernel_is_the_per_sample_path_to_the_bit() {
    let e = log();
    let theta3 = [1.1 * SPM_MOTOR.r_s, 0.9 * SPM_MOTOR.l_d, 1.05 * SPM_MOTOR.k_e()];
    let theta4 = [theta3[0], theta3[1], theta3[2], 5.0];
    let reference = VoltageInput::REFERENCE;
    for hold in [VoltageHold::Stator, VoltageHold::Dq] {
        let inverters: &[Option<InverterModel>] =
            if hold == VoltageHold::Stator { &[None, Some(InverterModel::default())] } else { &[None] };
        for inverter in inverters {
            let setup = PmsmSetup {
                n_p: SPM_MOTOR.n_p,
                hold,
                input: if inverter.is_some() { reference } else { VoltageInput::Terminal },
                inverter: *inverter,
                ..PmsmSetup::new(SPM_MOTOR.n_p, hold)
            };
            let m = PmsmSpm::from_setup(setup);
            let theta: &[f64] = if inverter.is_some() { &theta4 } else { &theta3 };
            for horizon in [None, Some(7), Some(1)] {
                let blocked = run(&m, &e, theta, horizon);
                let per_sample = run(&PerSample(PmsmSpm::from_setup(setup)), &e, theta, horizon);
                assert_eq!(blocked.len(), e.len());
                assert!(
                    blocked == per_sample,
                    "{hold} hold, inverter {inverter:?}, horizon {horizon:?}: the kernel differs from the per-sample path"
                );
            }
            // The normal equations on either, with x0 estimated.
            let a = normal_equations(&m, &e, theta);
            let b = normal_equations(&PerSample(PmsmSpm::from_setup(setup)), &e, theta);
            assert_eq!(
                (a.cost, &a.jtj, &a.jtr),
                (b.cost, &b.jtj, &b.jtr),
                "{hold} hold, inverter {inverter:?}"
            );
        }
    }
}

/// Inputs that do not cover the record (a hand-built `IntervalSource` shorter than the
/// context, or inverter directions missing) turn the block and the state non-finite, which
/// the caller reports, instead of a panic.
#[test]
fn the_spm_block_kernel_rejects_inputs_shorter_than_the_record() {
    use greybox::model::{Block, BlockContext, BlockKernel, GreyBoxModel, SimState};
    use greybox::pmsm::SpmInputs;
    use greybox::pmsm::{C64, IntervalSource, IntervalVoltage, PmsmSpm, VoltageHold};
    let n = 100;
    let y: Vec<greybox::data::Values> = vec![vec![0.0; n].into(), vec![0.0; n].into()];
    let ctx = BlockContext { n, horizon: None, measured: &y };
    let short =
        |u: IntervalVoltage, w: usize| IntervalSource { h: 1e-4, n_p: 4.0, w_m: vec![1.0; w].into(), u };
    let cases = [
        (short(IntervalVoltage::Start(vec![C64::default(); 9]), 10), 0),
        (short(IntervalVoltage::Terminal(vec![1.0; n].into(), vec![1.0; 50].into()), n), 0),
        (short(IntervalVoltage::Start(vec![C64::default(); n - 1]), n), 3),
    ];
    for (i, (source, dt)) in cases.into_iter().enumerate() {
        // The third case asks for the inverter model (4 parameters) with 3 directions.
        let m = PmsmSpm::new(4, VoltageHold::Stator);
        let m = if dt > 0 { m.with_inverter(Default::default()) } else { m };
        let theta: Vec<f64> = [1.0, 5e-3, 0.1, 0.5][..m.parameters().len()].to_vec();
        let inp = SpmInputs { source, dt: vec![C64::default(); dt] };
        let c = m.coefficients(&theta, &inp).unwrap();
        let mut st = SimState::new(&[0.0, 0.0], theta.len(), false);
        let mut b = Block::new(2, theta.len(), 0, true);
        b.len = n;
        m.run(&c, &inp, &ctx, &mut st, &mut b);
        assert!(st.x.iter().all(|x| x.is_nan()), "case {i}: state {:?}", st.x);
        assert!(b.y(0).iter().all(|x| x.is_nan()), "case {i}");
    }
}

/// A trial pass bounded by a cost: abandoned (`None`) when its cost exceeds the bound, the
/// unbounded pass to the bit otherwise (the solver's early rejection of far trial points).
#[test]
fn a_bounded_pass_is_abandoned_above_its_bound_and_exact_below() {
    use greybox::estimate::LeastSquares;
    let e = log();
    let m = PmsmSpm::from_setup(PmsmSetup::new(SPM_MOTOR.n_p, VoltageHold::Stator));
    let theta = [1.3 * SPM_MOTOR.r_s, 0.7 * SPM_MOTOR.l_d, 1.1 * SPM_MOTOR.k_e()];
    let opts = ProblemOptions { estimate_x0: true, ..Default::default() };
    let pb =
        PemProblem::new(&m, vec![(Prepared::new(&m, &e).unwrap(), None)], &theta, &NominalScaling, &opts)
            .unwrap();
    let p = pb.start_vector(&theta);
    let ne = LeastSquares::normal_equations(&pb, &p).unwrap();
    assert!(ne.cost > 0.0);
    for bound in [ne.cost, 1.5 * ne.cost, f64::INFINITY] {
        let b = pb.normal_equations_below(&p, bound).unwrap().expect("within its bound");
        assert_eq!(b.cost.to_bits(), ne.cost.to_bits());
        assert_eq!(format!("{:?} {:?}", b.jtj, b.jtr), format!("{:?} {:?}", ne.jtj, ne.jtr));
    }
    for bound in [0.0, 0.01 * ne.cost, 0.999 * ne.cost] {
        assert!(pb.normal_equations_below(&p, bound).unwrap().is_none(), "bound {bound}");
    }
}
