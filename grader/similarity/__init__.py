"""Academic integrity across a class: which submissions are alike in their source and in what their
code did, how unusual that is in this class, and which match a known (public) solution.

* ``files``: the counted source files and the snapshot ``grader grade`` keeps in ``OUT/<id>/source/``;
* ``code``: source similarity with copydetect (winnowed fingerprints; boilerplate and common code removed);
* ``behaviour``: behaviour fingerprints from the recorded bags and result.json (``fingerprint.json``
  per scenario, written when the bag is analyzed);
* ``compare``: behaviour similarity of every pair, weighed by rarity in the class and by what the lab forces;
* ``run``: ``grader similarity OUT`` (``OUT/similarity/``: similarity.json, pairs.csv, pair pages);
* ``page``: the side-by-side page of a pair and the class view's section; ``cli``: the command.

Nothing here calls anything cheating: it says what is similar and how unusual that is.
"""
