"""Motion engine: mocap data, virtual sensors, motion-graph synthesis (seed 000), OLNG (003), HMM (004),
marker labeling (001) and skeleton fitting (002). Pure numpy/scipy; never imports `gui`."""
