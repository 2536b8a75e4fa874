"""Ready-made blocks any scenario may use: signal sources, input files, recordings played
back as an FMU's outputs, and a co-simulation FMU run as a sampled block."""
