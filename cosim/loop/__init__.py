"""The loop: the system (slaves, blocks, connections), the fixed-step algorithm, its C
steps, the recorder (libcosim's observer), the manipulators and the checks between chunks."""
