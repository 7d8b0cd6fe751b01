//! The real-time driver of `plcd run`.
pub mod sys;
