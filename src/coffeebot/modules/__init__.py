"""Board tasks: each module reads declared topics and publishes declared topics."""
