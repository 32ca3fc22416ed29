"""Pure navigation algorithms: routes, speed profile, local costmap and DWA, delivery lifecycle."""
