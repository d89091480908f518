"""The worker: claims jobs from the store, runs them with the engine, stores the results."""
