"""Recording: hilrig sessions as MCAP files that Rerun, Foxglove, PlotJuggler and rosbag2 open."""
