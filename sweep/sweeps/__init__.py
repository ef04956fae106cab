"""Floor 4: sweeps -- configurations, designs and the chunked runner."""
