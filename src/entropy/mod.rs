//! Entropy coding (spec §6): discretized-Gaussian frequency tables, escapes, ANS.
