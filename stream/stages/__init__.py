"""The stages computed on each tracked frame: strain (extensometers), force, contraction (Poisson), stress."""
