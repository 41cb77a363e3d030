//! The plant as a chain: bodies (J, b) joined by S stages, each a compliant member in series
//! with a backlash (docs/model.md §1 for one stage, docs/model.md §10 for several),
//! stepped exactly between switches of any stage (docs/model.md §2).
//!
//! Stage i joins body i to body i + 1: u_i = a_i θ_i − c_i θ_{i+1}, ψ_i = K_i dz(u_i, g_i), body i
//! receives −a_i ψ_i and body i + 1 receives +c_i ψ_i; τ_m drives body 0 and τ_L acts on body S.
//! §1's shaft is a = c = 1, K = k, g = Δ; the belt a = R_1, c = α_1, K = K_b, g = α_2 Δ; docs/model.md §10's
//! stages a = 1, c = n_j. A mode is the tuple of the stages' modes.
//!
//! Data flow: [`ChainParams`] → [`Chain`] (validated) → [`ChainStepper`] over [`ChainState`]
//! ([`OneStageStepper`], [`TwoStageStepper`] for S = 1, 2), and [`ChainBound`]: the speed-error
//! bound under a PI loop on the motor speed, one disturbance per stage. A stage may carry a
//! damper (docs/model.md §1's two laws: its slack and capped modes, its force's surfaces, its V
//! for the bound's damper term), the last body a web span (docs/model.md §8), and every body
//! Coulomb friction with stiction (its modes forward, backward and stuck, their surfaces the
//! speed and the held torque).
//!
//! Stepping is docs/model.md §2 with one switching coordinate per stage: a piece is accepted
//! whole only when the cubic test certifies every stage's u free of its thresholds over it;
//! otherwise each uncertified stage's u is searched on the piece's Taylor expansion, the
//! earliest crossing among all stages is refined to round-off, every stage that crosses
//! within a few ulps of the step's time of it switches there too, and the piece continues
//! in the new mode. A touch that begins and ends inside one piece is therefore found: the
//! piece cannot be certified across it.

mod bound;
mod linear;
mod params;
mod state;
mod stepper;
mod vector_field;

pub use bound::{
    chain_loop, disturbance_column, friction_column, loop_poles, ChainBound, FrictionBound, LoopLayout, OneStageBound,
    OneStageFrictionBound, TwoStageBound,
};
pub use linear::{mode_matrix, Layout, Rows};
pub use params::{Body, Chain, ChainError, ChainParams, Coulomb, Part, Stage};
pub use state::{mode_of, BodyMode, ChainMode, ChainState, Motion};
pub use stepper::{
    BodySwitch, ChainEvent, ChainStepper, OneStageStepper, OneStageWebStepper, StageSwitch, TwoStageStepper,
};
