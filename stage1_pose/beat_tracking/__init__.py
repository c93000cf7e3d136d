"""The learned beat and downbeat tracker: a temporal convolutional network over log-mel frames
(:mod:`.model`, :mod:`.spectrogram`), a bar-pointer Viterbi decoder (:mod:`.decoder`), both end to end in
:mod:`.tracker`, and its training (:mod:`.train`; the corpus and the command are in
``benchmarks/train_beat_tracker.py``). The method page is ``docs/methods/beat_tracking.md``.
"""
