//! Independent computations the physics tests compare against (docs/model.md §1–§3).

pub mod closed_form;
pub mod closed_loop;
pub mod expm;
pub mod harness;
pub mod reference;
pub mod rigs;
pub mod taylor;
pub mod web_reference;
