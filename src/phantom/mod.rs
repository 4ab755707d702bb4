//! Synthetic CBCT cases with known truth: the imaging model (and, with the atlas, the patient
//! anatomy and the case writer).

pub mod imaging;
pub mod scene;
