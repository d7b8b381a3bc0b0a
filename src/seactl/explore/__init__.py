"""``seactl explore``: an interactive explorer of one SEA design in the browser.

The package is split so that everything but the page itself is testable without a
browser or Bokeh:

* :mod:`seactl.explore.model` - pure functions from control values to the data every
  view shows (all numbers from the public API: :func:`seactl.design` and its methods,
  :func:`seactl.loop_model`, :func:`seactl.imp_passivity.passivity`), the exports (TOML,
  JSON, the equivalent command line) and the validation of uploaded actuator files;
* :mod:`seactl.explore.app` - the Bokeh document (widgets, figures, callbacks);
* :mod:`seactl.explore.server` - the Bokeh server bound to a loopback address.

Neither ``import seactl`` nor the command line imports this package before
``seactl explore`` runs, so Bokeh stays an optional dependency (the ``app`` extra).
"""
