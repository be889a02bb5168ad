//! The regression model of the per-cell indirect light: per-cell features and the label of a
//! view ([`features`]), the least-squares solver with feature selection ([`regression`]) and the
//! fitted model with its JSON document ([`model`]).

pub mod features;
pub mod model;
pub mod regression;
