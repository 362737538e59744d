def main():
    print("tactex")
