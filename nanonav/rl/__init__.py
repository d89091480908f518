"""Deep learning from outside the engine: NanoNav's own trainer (``ppo``: the loop, GAE and
its config; ``networks``; ``checkpoint``; ``export`` to ONNX; ``training``, a run in a folder
as ``nanonav train`` makes it), and policies from outside the engine: a network's decisions
evaluated as a job evaluates a table (``evaluate``), and networks sent as ONNX models, checked
and run (``onnx_policy``)."""
