//! The motor models: the parameter file, the time-domain plant, the steady-state thrust model
//! (constant speed and with the slider's inertia), the effect library, and the root finder they
//! share.
pub mod contact_friction;
pub mod contact_profile;
pub mod effects;
pub mod params;
pub mod plant;
pub mod roots;
pub mod steady;
pub mod steady_contact;
pub mod steady_inertia;
