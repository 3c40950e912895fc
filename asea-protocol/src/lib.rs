//! The ASEA robot-computer link (seed 001 §5.2; wire definition in `docs/protocol.md`).
