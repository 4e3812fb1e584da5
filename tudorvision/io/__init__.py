"""tudorvision.io"""
__all__: list[str] = []
