/* An empty translation unit for the module-graph probe's stand-in libraries. */
int avsi_module_graph_probe;
