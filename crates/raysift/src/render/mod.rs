//! Renderers built on the Tracer contract.
