"""``seactl explore``: an interactive explorer of one SEA design in the browser.

The package is split so that everything but the page itself is testable without a
browser or Bokeh:

* :mod:`seactl.apps.explore.model` - pure functions from control values to the data every
  view shows (all numbers from the public API: :func:`seactl.design` and its methods,
  :func:`seactl.loop_model`, :func:`seactl.systems.sea.passivity.passivity`), the exports (TOML,
  JSON, the equivalent command line) and the validation of uploaded actuator files;
* :mod:`seactl.apps.explore.app` - the Bokeh document (widgets, figures, callbacks);
* :mod:`seactl.apps.explore.server` - the Bokeh server bound to a loopback address.

Neither ``import seactl`` nor the command line imports this package before
``seactl explore`` runs, so Bokeh stays an optional dependency (the ``app`` extra).
"""
