//! The integration tests, one module per topic, in one test binary (`it`): one link
//! instead of one per file. Tests that read the development logs in `../shared/data`
//! (not part of the repository) are reported as ignored when the folder is absent (the
//! build script's cfg `shared_data`), and skip with one line on stderr if it goes missing
//! after the build; see `common::require_shared!`.

mod common;
mod compensated;

mod agreement;
mod batch;
mod blocks;
mod cli_traps;
mod columnar;
mod coverage;
mod coverage_drive;
mod criteria;
mod csv_reader;
mod data;
mod delimiter;
mod design;
mod drive;
mod early_stop;
mod errors;
mod examples;
mod filter;
mod flux_map_cli;
mod flux_map_regions;
mod fuzz;
mod gate;
mod geodesic;
mod inverter;
mod ipm;
mod joint;
mod kalman;
mod kept_sums;
mod last_pass;
mod limits;
mod linear;
mod mechanics;
mod mgh;
mod mgh_exceptions;
mod mgh_problems;
mod multi_experiment;
mod nist;
mod noisy_inputs;
mod online;
mod outputs;
mod plots;
mod progress;
mod pwm_model;
mod pwm_noise;
mod pwm_trust;
mod random_starts;
mod ratings;
mod recovery;
mod reference;
mod reports;
mod robust;
mod saturation;
mod solver_agreement;
mod solvers;
mod spm;
mod standstill;
mod static_gate;
mod steady;
mod streamed;
mod telemetry;
mod thermal;
mod time_check;
mod track;
mod trust;
mod window;
