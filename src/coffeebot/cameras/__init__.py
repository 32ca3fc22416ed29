"""Fixed ceiling cameras (seed 003): what they see, which robot is which, where it is."""
