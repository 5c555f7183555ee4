//! Reconstruction: from images to a density. The problem (scene, target
//! images, the paper's setup and numbers), the visual hull, the resolution
//! levels of coarse-to-fine training, the gradients of the loss with respect
//! to the model's parameters and the one estimator vocabulary that chooses
//! among them, many-seed samples of those estimators for studying them,
//! the training loop and the refinement, the two methods with their shipped
//! defaults ([`methods`]) and the study files that change any setting
//! ([`study`]), progress and ETA, a whole reconstruction and the files it
//! is written to.

pub mod estimator;
pub mod grad_study;
pub mod hull;
pub mod level;
pub mod methods;
pub mod outputs;
pub mod paper;
pub mod param_grad;
pub mod problem;
pub mod progress;
pub mod reconstruct;
pub mod refine;
pub mod study;
pub mod train;
