"""The model library: what is known of each model (its index), keyword search over it, fast mesh reads, target scenes
composed from its models."""
