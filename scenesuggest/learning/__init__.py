"""What is learned from a corpus: its support edges and pairs as records, the counts, the wrapped angle histograms, the
pair priors, the orientation evidence and its weights, and the priors file that holds them all."""
