"""Results as PNG bytes: every picture NanoNav draws, in one place.

- ``figure``: the figure on the Agg canvas and its PNG bytes, which every picture is made of.
- ``job``: the pictures of one simulation result, a module per picture (``heatmap``,
  ``trajectory``, ``concentration``, ``learning``, ``qtable``); ``job.render`` and
  ``job.render_all`` draw them by name.
- ``study``: the pictures of a study, a metric across the grid and the mean learning curves,
  from its report; ``study.charts`` draws the summarised series they are made of.

The view is kept apart from the model: nothing here runs a simulation or reads a store, and the
engine never imports this package. pyplot and its global state are never used.
"""
