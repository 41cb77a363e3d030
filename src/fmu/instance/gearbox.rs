//! The calls of a two-stage gearbox's instance (`BacklashTwoStage`, docs/model.md §10) that
//! read or move its physics ([`Geared`]): the variables computed from the chain, Co-Simulation
//! steps, Model Exchange's state, derivatives, event indicators and Jacobian. Argument checks,
//! the state machine and the stored values are the instance's, shared with every model; each
//! entry point of the single-gap plants hands a gearbox here.

use super::lifecycle::Lifecycle;
use super::Instance;
use crate::fmu::adapter::{Calculated, GearQuantity, Source, StateEntry};
use crate::fmu::error::{FmuError, Status};
use crate::fmu::geared::{self, Geared, INDICATORS};
use crate::fmu::logging::LogCategory;
use crate::fmu::state_machine::Interface;
use crate::fmu::variables::Variable;
use crate::physics::chain::ChainEvent;
use crate::physics::vector_field::contact_surface_rates;
use crate::physics::{BoundError, Inputs};

/// The index of a gearbox's event indicator among [`Geared::indicators`], None for another
/// quantity.
pub(crate) fn indicator(quantity: Calculated) -> Option<usize> {
    use GearQuantity::*;
    Some(match quantity {
        Calculated::Gear(UMinusG1) => 0,
        Calculated::Gear(UPlusG1) => 1,
        Calculated::Gear(ForceUpper1) => 2,
        Calculated::Gear(ForceLower1) => 3,
        Calculated::Gear(CapUpper1) => 4,
        Calculated::Gear(CapLower1) => 5,
        Calculated::Gear(UMinusG2) => 6,
        Calculated::Gear(UPlusG2) => 7,
        Calculated::Gear(ForceUpper2) => 8,
        Calculated::Gear(ForceLower2) => 9,
        Calculated::Gear(CapUpper2) => 10,
        Calculated::Gear(CapLower2) => 11,
        Calculated::StopM => 12,
        Calculated::BreakawayM => 13,
        Calculated::Gear(StopI) => 14,
        Calculated::Gear(BreakawayI) => 15,
        Calculated::StopL => 16,
        Calculated::BreakawayL => 17,
        _ => return None,
    })
}

/// A row of the gearbox's Jacobian an importer may ask for (docs/model.md §6).
#[derive(Clone, Copy)]
enum Unknown {
    Derivative(usize),
    State(usize),
    Psi(usize),
    Indicator(usize),
    /// The bound: a function of time (and the trajectory's variation, which no state change
    /// moves), so its row is 0.
    TimeOnly,
}

impl Instance {
    /// The gearbox in force: after initialization its physics, before it the one the current
    /// values describe (built once per change).
    pub(super) fn gearbox(&mut self) -> Result<&Geared, FmuError> {
        if let Lifecycle::Setup {
            geared: slot @ None, ..
        } = &mut self.life
        {
            *slot = Some(Box::new(Geared::build(self.model, &self.values)?));
        }
        match &self.life {
            Lifecycle::Geared { sim, .. } | Lifecycle::Setup { geared: Some(sim), .. } => Ok(sim),
            _ => Err(FmuError::InvalidArgument(format!(
                "{} is not a two-stage gearbox",
                self.model.identifier
            ))),
        }
    }

    fn gear_inputs(&self) -> Inputs {
        geared::inputs(&self.values, &self.input_slopes)
    }

    /// The bound at the instance's time (as [`Instance::bound_to_time`]).
    fn gear_bound_to_time(&mut self) -> Result<(), FmuError> {
        let elapsed = self.time - self.experiment.start_time;
        let model_exchange = self.flavour.interface == Interface::ModelExchange;
        let time = self.time;
        let Some(g) = self.life.geared_mut() else {
            return Ok(());
        };
        match model_exchange {
            true => g.clock.at(elapsed),
            false => g.clock.current(),
        }
        .map_err(|e| match e {
            BoundError::Overflow { bound, .. } => {
                FmuError::Overflow(format!("the bound at t = {time} overflows: bound = {bound:e}"))
            }
            e => e.into(),
        })
    }

    /// Whether `bound` is +∞ here (with a damper in Model Exchange, [`Geared::bounded`]).
    pub(super) fn gear_unbounded(&mut self) -> bool {
        let model_exchange = self.flavour.interface == Interface::ModelExchange;
        self.gearbox().is_ok_and(|g| !g.bounded(model_exchange))
    }

    /// A Real variable of a gearbox: a state (its start value before initialization), a state
    /// derivative, or a quantity computed from the chain.
    pub(super) fn gear_real(&mut self, v: &Variable) -> Result<f64, FmuError> {
        match v.symbol.source() {
            Source::State(entry) => Ok(match self.life.geared() {
                Some(g) => g.entry(entry),
                None => self.values[v.symbol.index()],
            }),
            Source::Derivative(entry) => Ok(self.gear_rates()?[entry.chain_index()]),
            Source::Calculated(quantity) => {
                if quantity == Calculated::Bound {
                    self.gear_bound_to_time()?;
                    if self.gear_unbounded() {
                        return Ok(f64::INFINITY);
                    }
                }
                let inputs = self.gear_inputs();
                let g = self.gearbox()?;
                Ok(match quantity {
                    Calculated::Gear(GearQuantity::Psi1) => g.psi(0),
                    Calculated::Gear(GearQuantity::Psi2) => g.psi(1),
                    Calculated::Bound => g.bound(),
                    Calculated::BoundSup => g.bound_sup(),
                    q => match indicator(q) {
                        Some(i) => g.indicators(&inputs)[i],
                        None => {
                            return Err(FmuError::InvalidArgument(format!(
                                "{} is no variable of a two-stage gearbox",
                                v.name
                            )))
                        }
                    },
                })
            }
            _ => Err(FmuError::InvalidArgument(format!(
                "{} is not computed from the gearbox",
                v.name
            ))),
        }
    }

    /// An Integer output of a gearbox: a stage's `contact`, a body's `sliding`.
    pub(super) fn gear_integer(&mut self, source: Source) -> Result<i32, FmuError> {
        let g = self.gearbox()?;
        Ok(match source {
            Source::StageContact(j) => g.contact(j),
            Source::Sliding(slot) => g.sliding(slot),
            _ => unreachable!("the caller passes the gearbox's Integer outputs"),
        })
    }

    /// z′ = d/dt [θ_m, ω_m, θ_i, ω_i, θ_L, ω_L] at the state in force and the current inputs.
    pub(super) fn gear_rates(&mut self) -> Result<[f64; 6], FmuError> {
        let inputs = self.gear_inputs();
        self.gearbox()?.rates(&inputs)
    }

    /// The states set by value reference after initialization (`entries` by z's index), the
    /// others unchanged: in Model Exchange with the friction modes held, in Co-Simulation by the
    /// law of stiction (as the single gap's, `set_values`).
    pub(super) fn gear_set_states(&mut self, entries: &[(StateEntry, f64)]) -> Result<(), FmuError> {
        let model_exchange = self.flavour.interface == Interface::ModelExchange;
        let inputs = self.gear_inputs();
        let Some(g) = self.life.geared_mut() else {
            return Ok(());
        };
        let mut z = g.z();
        for (entry, value) in entries {
            z[entry.chain_index()] = *value;
        }
        let state = g.state_at(&z, (!model_exchange).then_some(&inputs))?;
        g.state = state;
        Ok(())
    }

    /// fmi2DoStep of a gearbox past the argument checks: the chain steps over `h` (to its first
    /// switch with `early_return`), each switch logged; returns the offset it stopped at.
    pub(super) fn gear_step(
        &mut self,
        communication_point: f64,
        h: f64,
        early_return: bool,
    ) -> Result<Option<f64>, FmuError> {
        let inputs = self.gear_inputs();
        let want_switches = self.log.is_enabled(LogCategory::ContactEvents);
        let overflow = |e: crate::physics::StepError| match e {
            crate::physics::StepError::Overflow => FmuError::Overflow(format!(
                "the step from t = {communication_point} overflows with tau_m = {:e}, tau_L = {:e} at its start; \
                 reduce the inputs, start values or parameters",
                inputs.tau_m, inputs.tau_l
            )),
            e => e.into(),
        };
        let g = self
            .life
            .geared_mut()
            .ok_or_else(|| FmuError::InvalidArgument("no gearbox before initialization has ended".into()))?;
        let mut switches = Vec::new();
        let before = g.state;
        let mut stopped = g
            .step(&inputs, h, early_return, &mut |e| {
                if want_switches {
                    switches.push(e)
                }
            })
            .map_err(overflow)?;
        // A switch that does not move time is no reason to return early: the whole step instead.
        if super::stepping::without_progress(communication_point, h, stopped) {
            switches.clear();
            g.state = before;
            stopped = g
                .step(&inputs, h, false, &mut |e| {
                    if want_switches {
                        switches.push(e)
                    }
                })
                .map_err(overflow)?;
        }
        let advanced = stopped.unwrap_or(h);
        if let Err(e) = g.check_stepped(
            &g.state,
            format_args!("the step to t = {} overflows", communication_point + advanced),
        ) {
            // A refused step changes nothing.
            g.state = before;
            return Err(e);
        }
        g.lag(advanced);
        let gaps = [g.half_gap(0), g.half_gap(1)];
        for e in switches {
            let t = communication_point + e.offset();
            self.log.emit(Status::Ok, LogCategory::ContactEvents, || match e {
                ChainEvent::Stage(s) => format!(
                    "contact switch of stage {} at t = {t} s: {:?} -> {:?} (g = {})",
                    s.stage + 1,
                    s.from,
                    s.to,
                    gaps[s.stage]
                ),
                ChainEvent::Body(b) => format!(
                    "friction switch of the {} at t = {t} s: {:?} -> {:?}",
                    geared::BODIES[b.body].1,
                    b.from,
                    b.to
                ),
            });
        }
        Ok(stopped)
    }

    /// Model Exchange's continuous states of a gearbox.
    pub(super) fn gear_set_continuous_states(&mut self, z: &[f64; 6]) -> Result<(), FmuError> {
        let g = self
            .life
            .geared_mut()
            .ok_or_else(|| FmuError::InvalidArgument("no gearbox before initialization has ended".into()))?;
        g.state = g.state_at(z, None)?;
        Ok(())
    }

    pub(super) fn gear_event_indicators(&mut self) -> Result<[f64; INDICATORS], FmuError> {
        let inputs = self.gear_inputs();
        Ok(self.gearbox()?.indicators(&inputs))
    }

    /// Model Exchange's Event Mode: the law of stiction on each body; whether a state changed.
    pub(super) fn gear_settle(&mut self) -> bool {
        let inputs = self.gear_inputs();
        self.life.geared_mut().is_some_and(|g| g.settle(&inputs))
    }

    /// The rows of the gearbox's Jacobian for `unknowns` (their sources), seeded by a change
    /// `dz` of z and `dtau` of τ_m, τ_L: J exact in the mode in force (docs/model.md §6).
    pub(super) fn gear_directional(
        &mut self,
        unknowns: &[(&'static str, Source)],
        dz: &[f64; 6],
        dtau: [f64; 2],
    ) -> Result<Vec<f64>, FmuError> {
        let mut rows = Vec::with_capacity(unknowns.len());
        for (name, source) in unknowns {
            rows.push(match source {
                Source::Derivative(e) => Unknown::Derivative(e.chain_index()),
                Source::State(e) => Unknown::State(e.chain_index()),
                Source::Calculated(Calculated::Gear(GearQuantity::Psi1)) => Unknown::Psi(0),
                Source::Calculated(Calculated::Gear(GearQuantity::Psi2)) => Unknown::Psi(1),
                Source::Calculated(Calculated::Bound) => Unknown::TimeOnly,
                Source::Calculated(q) if indicator(*q).is_some() => Unknown::Indicator(indicator(*q).unwrap_or(0)),
                _ => {
                    return Err(FmuError::InvalidArgument(format!(
                        "{name} is not an unknown of the Jacobian: the unknowns are the state derivatives and the \
                         outputs"
                    )))
                }
            });
        }
        let inputs = self.gear_inputs();
        let g = self.gearbox()?;
        let chain = g.chain();
        let (jz, jinputs) = chain.jacobian(&g.state);
        let mut full = dz.to_vec();
        full.push(0.0);
        // The change of every stage's u and u′ (linear in z), and of τ_h for a stuck body.
        let d = chain.state_at(&full);
        let d_inputs = Inputs {
            tau_m: dtau[0],
            tau_l: dtau[1],
            dtau_m: 0.0,
            dtau_l: 0.0,
            span: 0.0,
            dspan: 0.0,
        };
        let mut indicator_rates = Vec::with_capacity(INDICATORS);
        for j in 0..2 {
            let s = chain.stage(j);
            indicator_rates.extend(contact_surface_rates(s.k, s.d(), s.g, s.damper.law, d.u[j], d.du[j]));
        }
        for b in 0..3 {
            let c = chain.body(b).friction;
            let (stop, breakaway) = match (c.tau_c > 0.0, g.state.mode.body(b)) {
                (false, _) => (0.0, 0.0),
                (true, crate::physics::chain::BodyMode::Stuck) => {
                    let tau_h = g.stepper.holding(&g.state, &inputs, b);
                    let change = g.stepper.holding_change(&g.state.mode, &d, &d_inputs, b);
                    (0.0, -tau_h.signum() * change)
                }
                (true, _) => (dz[2 * b + 1], 0.0),
            };
            indicator_rates.extend([stop, breakaway]);
        }
        let mut values = Vec::with_capacity(rows.len());
        for row in rows {
            let value = match row {
                Unknown::Derivative(i) => {
                    (0..6).map(|k| jz[i][k] * dz[k]).sum::<f64>() + jinputs[i][0] * dtau[0] + jinputs[i][1] * dtau[1]
                }
                Unknown::State(i) => dz[i],
                Unknown::Psi(j) => {
                    let s = chain.stage(j);
                    let (ks, kd) = g.state.mode.stages()[j].force_slopes(s.k, s.d());
                    ks * d.u[j] + kd * d.du[j]
                }
                Unknown::Indicator(i) => indicator_rates[i],
                Unknown::TimeOnly => 0.0,
            };
            if !value.is_finite() {
                return Err(FmuError::Overflow(format!(
                    "a directional derivative evaluates to {value}"
                )));
            }
            values.push(value);
        }
        Ok(values)
    }

    /// fmi2GetDirectionalDerivative of a gearbox (the caller checked the interface and lengths):
    /// the seeds as a change of z and of τ_m, τ_L, the rows computed in full before any is
    /// written.
    pub(super) fn gear_directional_derivative(
        &mut self,
        unknowns: &[u32],
        knowns: &[u32],
        dv_known: &[f64],
        dv_unknown: &mut [f64],
    ) -> Result<Status, FmuError> {
        let real = crate::fmu::variables::VarType::Real;
        let mut dz = [0.0; 6];
        let mut dtau = [0.0; 2];
        for (vr, dv) in knowns.iter().zip(dv_known) {
            let v = self.typed_variable(*vr, real)?;
            if !dv.is_finite() {
                return Err(FmuError::ValueRefused {
                    name: v.name,
                    value: *dv,
                    range: "a finite seed".into(),
                });
            }
            match v.symbol.source() {
                Source::State(entry) => dz[entry.chain_index()] += dv,
                Source::Input(slot) if slot < 2 => dtau[slot] += dv,
                _ => {
                    return Err(FmuError::InvalidArgument(format!(
                        "{} is not a known of the Jacobian: the knowns are the continuous states and the inputs",
                        v.name
                    )))
                }
            }
        }
        let mut rows = Vec::with_capacity(unknowns.len());
        for vr in unknowns {
            let v = self.typed_variable(*vr, real)?;
            rows.push((v.name, v.symbol.source()));
        }
        let values = self.gear_directional(&rows, &dz, dtau)?;
        dv_unknown.copy_from_slice(&values);
        Ok(Status::Ok)
    }

    /// The rates of a gearbox's outputs (fmi2GetRealOutputDerivatives, order 1): the states',
    /// each ψ_j's, and the bound's.
    pub(super) fn gear_output_rate(&mut self, source: Source) -> Result<Option<f64>, FmuError> {
        let z_dot = self.gear_rates()?;
        let g = self.gearbox()?;
        Ok(match source {
            Source::State(e) => Some(z_dot[e.chain_index()]),
            Source::Calculated(Calculated::Gear(GearQuantity::Psi1 | GearQuantity::Psi2)) => {
                let j = usize::from(source == Source::Calculated(Calculated::Gear(GearQuantity::Psi2)));
                let chain = g.chain();
                let mut full = z_dot.to_vec();
                full.push(0.0);
                let d = chain.state_at(&full);
                let s = chain.stage(j);
                let (ks, kd) = g.state.mode.stages()[j].force_slopes(s.k, s.d());
                Some(ks * d.u[j] + kd * d.du[j])
            }
            Source::Calculated(Calculated::Bound) => {
                let chain = g.chain();
                // Each stage's variation grows at |u_j′| off ordinary contact (docs/model.md §10).
                let damped = (0..2).any(|j| chain.stage(j).d() > 0.0);
                if damped {
                    None
                } else {
                    Some(g.clock.bound.bound_rate())
                }
            }
            _ => None,
        })
    }

    /// fmi2GetRealOutputDerivatives of a gearbox (the caller checked the lengths): order 1 of
    /// each output that has one.
    pub(super) fn gear_output_derivatives(
        &mut self,
        vrs: &[u32],
        orders: &[i32],
        out: &mut [f64],
    ) -> Result<Status, FmuError> {
        if self.life.geared().is_none() {
            return Err(FmuError::InvalidArgument(
                "no output derivatives before initialization has ended".into(),
            ));
        }
        self.gear_bound_to_time()?;
        let mut rates = Vec::with_capacity(vrs.len());
        for (vr, order) in vrs.iter().zip(orders) {
            let v = self.typed_variable(*vr, crate::fmu::variables::VarType::Real)?;
            if v.causality != crate::fmu::variables::Causality::Output {
                return Err(FmuError::InvalidArgument(format!("{} is not an output", v.name)));
            }
            if *order != 1 {
                return Err(FmuError::InvalidArgument(format!(
                    "derivative order {order} of {}: maxOutputDerivativeOrder is 1",
                    v.name
                )));
            }
            let rate = self
                .gear_output_rate(v.symbol.source())?
                .ok_or_else(|| FmuError::InvalidArgument(format!("{} has no output derivative", v.name)))?;
            if !rate.is_finite() {
                return Err(FmuError::Overflow(format!("d{}/dt evaluates to {rate}", v.name)));
            }
            rates.push(rate);
        }
        out.copy_from_slice(&rates);
        Ok(Status::Ok)
    }

    /// The gearbox's nominals of z.
    pub(super) fn gear_nominals(&mut self) -> Result<Vec<f64>, FmuError> {
        Ok(self.gearbox()?.chain().state_nominals()[..6].to_vec())
    }

    /// z of the gearbox in force.
    pub(super) fn gear_z(&mut self) -> Result<[f64; 6], FmuError> {
        Ok(self.gearbox()?.z())
    }

    /// fmi2ExitInitializationMode of a gearbox: its physics from the values, checked (finite
    /// accelerations), with a warning where `bound_sup` or `bound` are +∞.
    pub(super) fn gear_exit_initialization(&mut self) -> Result<Status, FmuError> {
        let preview = match &mut self.life {
            Lifecycle::Setup { geared, .. } => geared.take(),
            _ => None,
        };
        let g = match preview {
            Some(g) => g,
            None => Box::new(Geared::build(self.model, &self.values)?),
        };
        g.rates(&self.gear_inputs())?;
        let model_exchange = self.flavour.interface == Interface::ModelExchange;
        let unbounded = match g.clock.bound.sup() {
            _ if !g.bounded(model_exchange) => Some((
                "bound",
                "with a damper (d_1 or d_2 > 0) in Model Exchange: the importer's solver steps through the dampers' \
                 slack and capped modes, whose trajectory term the bound needs"
                    .to_string(),
            )),
            Err(why) => Some(("bound_sup", why.to_string())),
            Ok(_) => None,
        };
        let slack = g.clock.bound.sup_slack();
        self.start_clock(self.experiment.start_time);
        self.life = Lifecycle::Geared {
            phase: self.initialized_phase(),
            sim: g,
        };
        self.initialization_warnings(unbounded, slack)
    }
}

/// z of a chain state as the gearbox's six entries.
pub(super) fn six(z: &[f64]) -> [f64; 6] {
    std::array::from_fn(|i| z[i])
}
