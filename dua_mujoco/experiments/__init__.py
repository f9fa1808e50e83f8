"""Paper reproduction and peer comparisons."""
