"""Scores: the measures (:mod:`.metrics`) and the real videos they are read on (:mod:`.real`)."""
