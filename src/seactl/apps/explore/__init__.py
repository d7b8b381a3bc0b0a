"""``seactl explore``: an interactive explorer of one SEA design or loop file in the browser.

The package is split so that everything but the page itself is testable without a
browser or Bokeh:

* :mod:`seactl.apps.explore.model` - pure functions from control values to the data every
  view shows (all numbers from the public API: :func:`seactl.design` and its methods,
  :func:`seactl.loop_model`, ``Design.passivity``), the exports (TOML,
  JSON, the equivalent command line), the validation of uploaded actuator files and the
  verdict badge;
* :mod:`seactl.apps.explore.loopmodel` - the same for a loop file (:func:`seactl.load_loop`,
  the :class:`seactl.UserLoop` views) and its command line;
* :mod:`seactl.apps.explore.robotmodel` - the same for a robot (``--robot URDF``:
  :func:`seactl.robot` at a configuration, its margins per loop break, impedance
  matrix and step; :func:`seactl.workspace_map` on request);
* :mod:`seactl.apps.explore.app` - the Bokeh document (widgets, figures, callbacks);
  :mod:`seactl.apps.explore.robotapp` the robot's;
* :mod:`seactl.apps.explore.server` - the Bokeh server bound to a loopback address.

Neither ``import seactl`` nor the command line imports this package before
``seactl explore`` runs, so Bokeh stays an optional dependency (the ``app`` extra).
"""
