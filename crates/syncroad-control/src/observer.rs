//! One trait for what watches a simulation loop without changing it: recording, the spread and
//! collision watch of the native simulator, and in the SUMO loop the safety counters, the rows
//! streamed to the parent and SUMO-side measurements. The loop owns the horizon and the stop
//! reason; after each step it hands its state `S` to each observer in turn (the argmin split of
//! a solver's step from the executor that runs it).

/// Something that runs around each step of a loop whose state is `S`.
pub trait StepObserver<S: ?Sized> {
    /// What can go wrong while observing (a broken pipe in the SUMO loop; nothing natively).
    type Error;

    /// Its name in a profile of the loop.
    fn name(&self) -> &'static str;

    /// The state before the first step.
    fn start(&mut self, _state: &mut S) -> Result<(), Self::Error> {
        Ok(())
    }

    /// After each step the loop observes.
    fn after_step(&mut self, state: &mut S) -> Result<(), Self::Error>;
}
