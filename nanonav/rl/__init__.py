"""Policies from outside the engine: a network's decisions evaluated as a job evaluates a table
(``evaluate``), and networks sent as ONNX models, checked and run (``onnx``)."""
