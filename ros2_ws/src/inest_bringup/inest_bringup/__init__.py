"""Starting and watching the INEST node graph."""
