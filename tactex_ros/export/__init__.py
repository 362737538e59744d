"""Open data: trial records, sessions and recorded presses as a dataset others load.

``hf.export`` writes a Hugging Face dataset (the ``datasets`` library, imported only here):
one row per touch, the contact image and the no-contact frame as lossless PNG, with a dataset
card (``README.md``). ``rows`` reads the rows of a record, a session, a folder of either, or a
``replay:DIR`` library; nothing here needs ROS or torch.
"""
