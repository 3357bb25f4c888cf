"""Re-simulation: a recorded session's valve commands fed into the model again, "what if"
(the library side of ``boom-resim``; see :mod:`.resimulation`)."""
