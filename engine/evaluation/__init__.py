"""Evaluation that looks like a user's take (issue 11): long continuous takes chained from held-out clips,
leave-one-group-out (content / style), baselines in the same table, and the metrics the issue judges by.

Modules (one job each):
    labels     -- content / style of a database clip (Bandai label JSON, else the file name)
    takes      -- held-out clips chained into one continuous take (root position and heading continuous)
    simulate   -- what the worn sensors and the overhead camera report on a take (from the truth)
    metrics    -- per-frame errors (global joint, root-relative joint, root position, heading), per-second traces
    baselines  -- database mean pose at the camera; per-window nearest neighbour on the sensor features
    engines    -- the motion graph, OLNG and HMM run on simulated inputs, as world joint positions
    protocols  -- chained takes and leave-one-group-out: which clips are held out, which rows are scored
    table      -- the printed tables
    cli        -- `courtside evaluate --protocol ...`
"""
