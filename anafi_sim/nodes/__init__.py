"""The nodes: one module per node (its class and main()), run by the thin scripts of anafi_sim/scripts."""
