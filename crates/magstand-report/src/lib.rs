//! Figures and reports that a person would rather look at than read.
//!
//! Every figure is SVG text drawn with plotters ([`chart`]), labelled with quantities and units,
//! in the colour-blind-safe Okabe-Ito palette. The same figures go inline into the HTML report
//! and, as standalone files, into papers.
//!
//! # Example
//! ```
//! use magstand_report::chart::{Series, XyChart};
//!
//! let svg = XyChart::new("demo", "Deviation against throttle", "throttle (0..1)", "deviation (µT)")
//!     .with(Series::dots("z axis", vec![(0.0, 0.0), (0.5, -3.0), (1.0, -16.0)], 0))
//!     .to_svg()?;
//! assert!(svg.starts_with("<svg") && svg.contains("deviation (µT)"));
//! # Ok::<(), magstand_report::ReportError>(())
//! ```
#![warn(missing_docs)]

mod assemble;
pub mod chart;
pub mod diagnosis;
mod error;
pub mod figures;
pub mod montecarlo;
pub mod page;

pub use assemble::{ReportInputs, build};
pub use error::ReportError;
pub use page::{Figure, Report, Section};
