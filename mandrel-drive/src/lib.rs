//! The mandrel drive: stepper indexer languages, simulator, sync lines (seed 001 §4.1.4–4.1.8).
